"""fleet: a multi-robot fleet orchestrator for ROS 2 Jazzy.

Stages (each a subpackage): spec (load and validate a fleet spec), expand (render per-robot
launch bundles from templates), runtime (run a launch description: the embedded runner),
nodes (the fleet_nodes ROS package), world (the shared PyBullet world), control (Zenoh router,
agents and client), testing (pytest plugin).  Heavy imports (rclpy, zenoh, pybullet) happen
only inside the modules that need them, never at package import.
"""

__version__ = "0.1.0"
