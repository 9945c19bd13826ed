"""Argument handling shared by `fleet_nodes/world` and `python -m fleet.nodes.world`."""

from __future__ import annotations

import argparse
import sys

from fleet.errors import EXIT_USAGE, FleetError


def world_main(argv: list[str]) -> int:
    """Run the world; invalid world.yaml -> `fleet: error: file:line:col: problem` and exit 2."""
    from rclpy.utilities import remove_ros_args

    full = ["world", *argv]
    parser = argparse.ArgumentParser(prog="world", description="The shared PyBullet world of a fleet.")
    parser.add_argument("--config", required=True, help="world.yaml")
    parser.add_argument("--status-file", default=None, help="JSON status written atomically a few times a second")
    parser.add_argument("--as-fast-as-possible", action="store_true", help="do not pace to the wall clock")
    parser.add_argument("--sim-duration", type=float, default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(remove_ros_args(full)[1:])
    try:
        from fleet.world.description import load_world

        load_world(args.config)  # fail fast with one line, before pybullet and rclpy load
        from fleet.world.app import run_world

        run_world(
            args.config,
            args.status_file,
            as_fast_as_possible=args.as_fast_as_possible,
            ros_args=full,
            sim_duration=args.sim_duration,
        )
    except FleetError as error:
        sys.stderr.write(error.line() + "\n")
        return error.exit_code or EXIT_USAGE
    except KeyboardInterrupt:
        return 130
    return 0
