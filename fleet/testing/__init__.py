"""Helpers for testing fleets: isolation (ROS domains, ports, processes) and the pytest plugin.

`running_fleet(spec)` brings a fleet up isolated from everything else on the machine and yields
a FleetHandle; the pytest plugin (fleet.testing.plugin) offers the same as the `fleet_up` fixture.
Imports stay light: rclpy, zenoh and pybullet load only when a fleet is used.
"""

from fleet.testing.fleet_handle import (
    FleetHandle,
    FleetLeak,
    FleetTimeout,
    NotSimulated,
    Pose,
    UnknownRobot,
    running_fleet,
)

__all__ = ["FleetHandle", "FleetLeak", "FleetTimeout", "NotSimulated", "Pose", "UnknownRobot", "running_fleet"]
