"""The `fleet` command.

Each command group lives in its own module with a `register(app)` function.  Modules import only
typer/rich at module level: rclpy, zenoh and pybullet are imported inside the command bodies so
that `fleet --help` stays fast.
"""

from __future__ import annotations

import gc
import sys

import typer

from fleet.cli import (
    certs_cmd,
    daemons_cmd,
    dashboard_cmd,
    deploy_cmd,
    render_cmd,
    robot_cmd,
    run_cmd,
    status_cmd,
    world_cmd,
)
from fleet.errors import COMMAND_LINE, EXIT_FAILURE, EXIT_USAGE, PYDANTIC_PREFIX, FleetError, Location

app = typer.Typer(
    name="fleet",
    help="Multi-robot fleet orchestrator for ROS 2 Jazzy.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    context_settings={"help_option_names": ["-h", "--help"]},
)


def _print_version(asked: bool) -> None:
    if not asked:
        return
    from importlib.metadata import PackageNotFoundError, version

    import fleet

    try:
        installed = version("fleet")
    except PackageNotFoundError:  # a checkout run without installing it
        installed = fleet.__version__
    print(f"fleet {installed}")
    raise typer.Exit()


@app.callback()
def _fleet(
    _version: bool = typer.Option(
        False, "--version", callback=_print_version, is_eager=True, help="Print fleet's version and exit."
    ),
) -> None:
    """Multi-robot fleet orchestrator for ROS 2 Jazzy.

    Typical flow: fleet render SPEC (see what a spec expands to), fleet deploy SPEC, fleet status.
    """


for _module in (
    render_cmd,
    run_cmd,
    daemons_cmd,
    deploy_cmd,
    status_cmd,
    robot_cmd,
    world_cmd,
    certs_cmd,
    dashboard_cmd,
):
    _module.register(app)


def entry_point() -> None:
    """The `fleet` program (console script and `python -m fleet`): main, then the exit."""
    try:
        main()
    finally:
        # The process is ending: spare the interpreter's exit its garbage collection passes over
        # every object typer, pydantic and zenoh made (frozen objects are skipped, not leaked).
        # At 1,000 robots: 0.90 of the time of `fleet status --json`, 0.92 of a no-op redeploy
        # (bench/README.md).  Not in main, which tests call in their own long-lived process.
        gc.freeze()


def main(argv: list[str] | None = None) -> None:
    """Run the command line: user errors become one line on stderr and their exit code (2 for bad input).

    Usage errors of the command line itself (unknown option, missing argument, a value of the
    wrong kind) too: click would draw a box of several lines, so it is asked to raise instead.
    """
    click = _click_exceptions()
    try:
        code = app(args=argv, prog_name="fleet", standalone_mode=False)
    except FleetError as error:
        from fleet.cli.output import print_error

        print_error(error)
        sys.exit(error.exit_code)
    except click.NoArgsIsHelpError as error:  # `fleet` alone, or a group without its command: the help is printed
        sys.exit(error.exit_code)
    except click.ClickException as error:
        from fleet.cli.output import print_error

        command = error.ctx.command_path if getattr(error, "ctx", None) else "fleet"
        message = error.format_message().replace(PYDANTIC_PREFIX, "")  # typer checks values with pydantic
        print_error(FleetError(f"{command}: {message}", Location(COMMAND_LINE)))
        sys.exit(EXIT_USAGE)
    except (typer.Abort, EOFError):
        sys.exit(EXIT_FAILURE)
    except KeyboardInterrupt:
        sys.exit(130)
    sys.exit(code if isinstance(code, int) else 0)


def _click_exceptions():
    """The click exceptions module typer uses (a vendored copy in recent typer versions)."""
    import importlib

    import typer.core

    click = getattr(typer.core, "_click", None) or importlib.import_module("click")
    return click.exceptions
