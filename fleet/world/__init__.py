"""The shared PyBullet world hosting every simulated robot of a fleet, and its ROS bridge.

Modules: description (world.yaml -> dataclasses, pure), geometry and lidar (pure 2D maths),
physics (pybullet, no ROS), ros_bridge (rclpy), status (status JSON), snapshot (matplotlib picture
from status data), app (main loop, live reload, pacing), cli (argument handling).
Import submodules directly: this package imports nothing heavy.
"""
