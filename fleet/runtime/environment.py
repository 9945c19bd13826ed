"""The environment of a fleet's ROS processes: one ROS domain, discovery kept on this host."""

from __future__ import annotations

import os


def ros_environment(domain_id: int, base: dict[str, str] | None = None) -> dict[str, str]:
    """An environment for ROS processes confined to one domain on this host."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy, conflicts with the range
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    # FastDDS's shared-memory transport leaves segments in /dev/shm when a process is killed
    # (fault injection kills many), and stale segments were seen to hang new participants at
    # creation.  UDP on loopback is plenty for robot topics; set the variable to override.
    env.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "UDPv4")
    env["PYTHONUNBUFFERED"] = "1"
    return env
