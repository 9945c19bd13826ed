"""How a fleet's ROS traffic crosses computers: DDS discovery servers and the Zenoh bridge."""
