"""Starting a robot's launch file the way an agent does under `isolation: agent`, for tests and
benchmarks that drive a HostPool without the control plane."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from fleet.runtime.hosting import HostPool
from fleet.runtime.supervisor import LaunchSession


def robot_of(launch_file: Path) -> str:
    """The robot a rendered launch file belongs to: `robot1.launch.yaml` -> `robot1`."""
    return launch_file.name.split(".", 1)[0]


def start_hosted_robot(launch_file: Path, pool: HostPool, env: Mapping[str, str], log_dir: Path) -> LaunchSession:
    """Start the robot's session, which runs as processes only the nodes that cannot be hosted,
    and hand the others (with the command lines launch_ros would give them) to `pool`."""
    session = LaunchSession(launch_file, env=dict(env), log_dir=log_dir, isolation="agent", backend="embedded")
    session.start()
    pool.add_robot(robot_of(launch_file), session.hosted_nodes(), session.log_dir)
    return session
