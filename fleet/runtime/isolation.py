"""Which OS processes a launch plan becomes.

`process` isolation: one process per node, as `ros2 launch` does.  `robot` isolation: the
fleet_nodes controller, battery and safety nodes of the launch share one `composite` process
(one rclpy runtime instead of three: the memory lever of DESIGN.md), each node keeping the exact
ROS arguments it would get alone; every other node still runs alone.  `agent` isolation: those
nodes are hosted instead by the agent's shared host processes (fleet.runtime.hosting, one for
up to group_size robots); the launch session runs only the others, each alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from fleet.runtime.ament import PACKAGE
from fleet.runtime.launch_file import NodeLaunch

ISOLATIONS = ("process", "robot", "agent")
HOSTED = "agent"  # the isolation whose composable nodes run in an agent's host processes
COMPOSABLE = ("controller", "battery", "safety")


@dataclass
class ProcessSpec:
    """One supervised process: what to run and which nodes live in it."""

    name: str  # `controller-1`, `composite-1`: log file name and screen prefix
    cmd: list[str]
    env: dict[str, str] = field(default_factory=dict)  # set_env variables for this process
    nodes: list[NodeLaunch] = field(default_factory=list)
    respawn: bool = False
    respawn_delay: float = 0.0
    echo: bool = False  # print its lines (output: screen or both)
    env_unset: tuple[str, ...] = ()  # unset_env variables for this process
    delay: float = 0.0  # seconds after the session starts (timer actions)
    cwd: str | None = None


def single(node: NodeLaunch) -> ProcessSpec:
    return ProcessSpec(
        name=node.process_name,
        cmd=list(node.cmd),
        env=dict(node.env),
        nodes=[node],
        respawn=node.respawn,
        respawn_delay=node.respawn_delay,
        echo=node.output in ("screen", "both"),
        env_unset=node.env_unset,
        delay=node.delay,
        cwd=node.cwd,
    )


def composable(node: NodeLaunch) -> bool:
    # Plain (non-ROS) arguments would have nowhere to go in the composite's argv; a node started
    # by a timer or with its environment pruned is started alone.
    return (
        node.package == PACKAGE
        and node.executable in COMPOSABLE
        and len(node.cmd) > 1
        and node.cmd[1] == "--ros-args"
        and node.delay == 0.0
        and not node.env_unset
        and node.cwd is None
    )


def composite(nodes: list[NodeLaunch], number: int) -> ProcessSpec:
    """`<lib>/fleet_nodes/composite --fleet-node EXE <its ros args> --fleet-node EXE ...`."""
    executable = Path(nodes[0].cmd[0]).parent / "composite"
    cmd = [str(executable)]
    for node in nodes:
        cmd += ["--fleet-node", node.executable, *node.ros_arguments]
    return ProcessSpec(
        name=f"composite-{number}",
        cmd=cmd,
        env=dict(nodes[0].env),
        nodes=list(nodes),
        respawn=any(node.respawn for node in nodes),
        respawn_delay=max(node.respawn_delay for node in nodes),
        echo=any(node.output in ("screen", "both") for node in nodes),
    )


def plan_processes(nodes: list[NodeLaunch], isolation: str = "process") -> list[ProcessSpec]:
    if isolation not in ISOLATIONS:
        raise ValueError(f"isolation must be one of {ISOLATIONS}, got {isolation!r}")
    if isolation == "process":
        return [single(node) for node in nodes]
    if isolation == HOSTED:  # the composable ones are the agent's to host
        return [single(node) for node in nodes if not composable(node)]
    # Nodes can share a process only if they need the same environment and the same
    # executable directory (the same fleet_nodes installation).
    groups: dict[tuple, list[NodeLaunch]] = {}
    for node in nodes:
        if composable(node):
            key = (tuple(sorted(node.env.items())), str(Path(node.cmd[0]).parent))
            groups.setdefault(key, []).append(node)
    shared = {id(node) for group in groups.values() if len(group) > 1 for node in group}
    specs: list[ProcessSpec] = []
    placed: set[tuple] = set()
    for node in nodes:
        if id(node) not in shared:
            specs.append(single(node))
            continue
        key = (tuple(sorted(node.env.items())), str(Path(node.cmd[0]).parent))
        if key not in placed:  # the composite takes the place of its first node
            placed.add(key)
            specs.append(composite(groups[key], len(placed)))
    return specs
