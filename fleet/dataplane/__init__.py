"""How a fleet's ROS traffic crosses computers: DDS discovery through a per-fleet server."""
