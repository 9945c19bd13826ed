"""`fleet run FILE.launch.yaml [name:=value ...]` and `fleet ament-prefix`."""

from __future__ import annotations

import sys
from enum import StrEnum
from pathlib import Path

import typer

from fleet.errors import EXIT_FAILURE, FleetError, Location


class Isolation(StrEnum):
    # `agent` is not here: its host processes belong to an agent (fleet deploy), which `fleet run` is not.
    process = "process"
    robot = "robot"


class Backend(StrEnum):
    auto = "auto"
    embedded = "embedded"
    ros2 = "ros2"


def _launch_args(items: list[str]) -> dict[str, str]:
    """`name:=value` items, refused as ros2 launch refuses them (also `name:=` with no value)."""
    result = {}
    for item in items:
        name, separator, value = item.partition(":=")
        if not separator or not name or (not value and item.count(":=") == 1):
            raise FleetError("launch arguments are name:=value", Location(item))
        result[name] = value
    return result


def _print_line(process: str, line: str) -> None:
    # One write per line, so lines of different nodes never interleave mid-line.  `ros2 launch`
    # prefixes its lines itself, and the session's own lines (process "") say what they are about.
    prefix = "" if not process or process.startswith("ros2-launch") else f"[{process}] "
    sys.stdout.write(f"{prefix}{line}\n")
    sys.stdout.flush()


def _node_of(status) -> str:
    """The node a process runs, by its full name ("" for an executable that is no node)."""
    return status.fqn or status.name or ""


def _summary(session) -> str:
    rows = [
        f"fleet: {session.path.name}: {session.backend} backend, isolation {session.isolation}, "
        f"logs in {session.log_dir}"
    ]
    for status in session.status():
        rows.append(f"  {status.process:<16} pid {status.pid or '-':<8} {_node_of(status)}".rstrip())
    return "\n".join(rows)


def run(
    file: Path = typer.Argument(..., help="A ROS 2 YAML launch file (.launch.yaml)."),
    launch_args: list[str] = typer.Argument(None, help="Launch arguments, name:=value."),
    # Choices: typer refuses another value (exit 2) before anything is read, also with -s and -p.
    isolation: Isolation = typer.Option(
        Isolation.process,
        "--isolation",
        help="process: one process per node; robot: the robot's fleet_nodes share one process "
        "(agent isolation is an agent's: fleet deploy).",
    ),
    backend: Backend = typer.Option(
        Backend.auto, "--backend", help="auto (ros2 launch when installed, else embedded), embedded, ros2."
    ),
    log_dir: Path = typer.Option(None, "--log-dir", help="Where node logs go (default ~/.ros/log/...)."),
    show_args: bool = typer.Option(
        False, "--show-args", "-s", help="Print the launch arguments the file declares (as ros2 launch -s)."
    ),
    print_description: bool = typer.Option(
        False, "--print", "-p", help="Print the launch description (as ros2 launch -p), start nothing."
    ),
) -> None:
    """Run a launch file in the foreground, like `ros2 launch FILE name:=value...`.

    Ctrl-C stops every node cleanly."""
    import signal
    import threading

    from fleet.runtime.supervisor import LaunchSession

    if show_args or print_description:
        from fleet.launchfile import read_launch_file
        from fleet.launchfile.show import arguments_text, description_text

        description = read_launch_file(file)
        print(arguments_text(description) if show_args else description_text(description))
        return
    session = LaunchSession(
        file,
        launch_args=_launch_args(launch_args or []),
        log_dir=log_dir,
        isolation=isolation.value,
        backend=backend.value,
        on_line=_print_line,
    )
    interrupted = threading.Event()

    def _on_signal(signum, frame):
        interrupted.set()

    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        session.start()
        sys.stderr.write(_summary(session) + "\n")
        sys.stderr.flush()
        # Like ros2 launch: run until interrupted or until every process has ended for good.
        while not interrupted.wait(0.2):
            if session.done():
                break
    finally:
        if session.backend is not None:
            sys.stderr.write("fleet: stopping\n" if interrupted.is_set() else "")
            session.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    failed = session.failed()
    for status in failed:
        sys.stderr.write(
            f"fleet: {status.process}{f' ({node})' if (node := _node_of(status)) else ''} failed with exit code "
            f"{status.exit_code}; log: {session.log_file(status.process)}\n"
        )
    if failed:
        raise typer.Exit(EXIT_FAILURE)


def ament_prefix() -> None:
    """Print the ament prefix holding fleet_nodes (add it to AMENT_PREFIX_PATH for ros2 launch)."""
    from fleet.runtime.ament import ensure_ament_prefix

    print(ensure_ament_prefix())


def register(app: typer.Typer) -> None:
    app.command("run")(run)
    app.command("ament-prefix")(ament_prefix)
