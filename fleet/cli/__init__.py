"""The `fleet` command.

Each command group lives in its own module with a `register(app)` function.  Modules import only
typer/rich at module level: rclpy, zenoh and pybullet are imported inside the command bodies so
that `fleet --help` stays fast.
"""

from __future__ import annotations

import sys

import typer

from fleet.cli import certs_cmd, control_cmd, dashboard_cmd, render_cmd, run_cmd, world_cmd
from fleet.errors import FleetError

app = typer.Typer(
    name="fleet",
    help="Multi-robot fleet orchestrator for ROS 2 Jazzy.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


@app.callback()
def _fleet() -> None:
    """Multi-robot fleet orchestrator for ROS 2 Jazzy.

    Typical flow: fleet render SPEC (see what a spec expands to), fleet deploy SPEC, fleet status.
    """


for _module in (render_cmd, run_cmd, control_cmd, world_cmd, certs_cmd, dashboard_cmd):
    _module.register(app)


def main(argv: list[str] | None = None) -> None:
    """Entry point: user errors become one line on stderr and their exit code (2 for bad input).

    Click (inside typer) handles usage errors itself, with exit code 2.
    """
    try:
        app(args=argv)
    except FleetError as error:
        from fleet.cli.output import print_error

        print_error(error)
        sys.exit(error.exit_code)
    except KeyboardInterrupt:
        sys.exit(130)
