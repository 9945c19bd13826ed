"""composite: several fleet nodes in one process (isolation: robot).

argv is a sequence of groups, each `--fleet-node EXEC --ros-args ...`: the executable name and
exactly the ROS arguments that node would get as a process of its own.  Each node is created
with cli_args=<its group> and use_global_arguments=False, so names, namespaces, parameter files,
-p values and remappings apply to that node only; all spin in one executor.  One process per
robot instead of three saves about two thirds of the memory of a large simulated fleet.
"""

from __future__ import annotations

import itertools
import sys
from functools import partial

from fleet.nodes import NODES, load_node_class

GROUP_FLAG = "--fleet-node"
PROGRAM = "composite"


class UsageError(ValueError):
    pass


def parse_groups(argv: list[str]) -> list[tuple[str, list[str]]]:
    """[(executable, ros arguments)] from the composite's arguments (without the program name)."""
    if not argv:
        raise UsageError(f"no nodes given; usage: {PROGRAM} {GROUP_FLAG} EXEC --ros-args ... [...]")
    if argv[0] != GROUP_FLAG:
        raise UsageError(f"arguments must start with {GROUP_FLAG} EXEC, got {argv[0]!r}")
    groups: list[tuple[str, list[str]]] = []
    i = 0
    while i < len(argv):
        # argv[i] is GROUP_FLAG here: the loop below stops only at one or at the end.
        if i + 1 >= len(argv) or argv[i + 1].startswith("-"):
            raise UsageError(f"{GROUP_FLAG} needs an executable name ({', '.join(sorted(NODES))})")
        executable = argv[i + 1]
        if executable not in NODES:
            raise UsageError(f"unknown node executable {executable!r} (known: {', '.join(sorted(NODES))})")
        j = i + 2
        while j < len(argv) and argv[j] != GROUP_FLAG:
            j += 1
        groups.append((executable, argv[i + 2 : j]))
        i = j
    return groups


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv if argv is None else argv)
    # Accept argv with or without the program name in front (sys.argv style or groups only).
    if args and args[0] != GROUP_FLAG:
        args = args[1:]
    try:
        groups = parse_groups(args)
    except UsageError as exc:
        print(f"{PROGRAM}: error: {exc}", file=sys.stderr, flush=True)
        return 2
    # Imported here so that a usage error is reported without paying for rclpy.
    from fleet.nodes.common import run

    factories = [partial(_create, exe, ros_args) for exe, ros_args in groups]
    # No global ROS arguments: everything belongs to some node's group.
    return run(PROGRAM, [PROGRAM], factories)


def log_levels(ros_args: list[str]) -> list[tuple[str | None, str]]:
    """The `--log-level [LOGGER:=]LEVEL` settings of a group, in order (None: the node's logger)."""
    found = []
    for flag, value in itertools.pairwise(ros_args):
        if flag == "--log-level":
            logger, _, level = value.rpartition(":=")
            found.append((logger or None, level))
    return found


def _create(executable: str, ros_args: list[str], **node_kwargs):
    node = load_node_class(executable)(cli_args=ros_args, use_global_arguments=False, **node_kwargs)
    # rcl applies --log-level only from the process's global arguments, at init; a node's own
    # cli_args would silently lose it, so apply it here to that node's logger.
    import rclpy.logging

    for logger, level in log_levels(ros_args):
        severity = rclpy.logging.get_logging_severity_from_string(level)
        if logger is None:
            node.get_logger().set_level(severity)
        else:
            rclpy.logging.set_logger_level(logger, severity)
    return node


if __name__ == "__main__":
    raise SystemExit(main())
