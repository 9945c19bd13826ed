"""Running a launch description: the embedded runner (launch_file, supervisor), the processes it
starts, their logs, and the ament index entries of the fleet_nodes package."""
