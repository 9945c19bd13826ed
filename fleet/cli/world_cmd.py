"""`fleet world` (run the shared PyBullet world) and `fleet snapshot` (picture of it)."""

from __future__ import annotations

from pathlib import Path

import typer

from fleet.cli.options import ConnectOption, ZenohConfigOption, client, fleet_option
from fleet.errors import FleetError, Location


def register(app: typer.Typer) -> None:
    @app.command("world")
    def world(
        config: Path = typer.Option(..., "--config", help="world.yaml describing obstacles and robots."),
        status_file: Path | None = typer.Option(
            None,
            "--status-file",
            help="Write the world's state here (JSON, atomically, a few times a second); "
            "robots restart from the poses in it.",
        ),
        as_fast_as_possible: bool = typer.Option(
            False, "--as-fast-as-possible", help="Do not pace to the wall clock (tests, benchmarks)."
        ),
    ) -> None:
        """Run the shared PyBullet world hosting every simulated robot (until Ctrl-C).

        Robots join and leave as world.yaml changes on disk.
        """
        from fleet.rules import directory_problem
        from fleet.world.description import load_world

        load_world(config)  # fail fast with one line, before pybullet and rclpy load
        if status_file is not None:  # the world writes it a few times a second, from the start
            if status_file.is_dir():
                raise FleetError("the status file is a directory: give a file's name", Location(status_file))
            if problem := directory_problem(status_file.parent):
                raise FleetError(f"the status file's directory {problem}", Location(status_file))
        from fleet.world.app import run_world

        run_world(config, status_file, as_fast_as_possible=as_fast_as_possible)

    @app.command("snapshot")
    def snapshot(
        output: Path = typer.Option(Path("world.png"), "-o", "--output", help="PNG to write."),
        fleet: str | None = fleet_option("Fleet whose world to draw (needed when several fleets run one).", "-f"),
        connect: str | None = ConnectOption,
        zenoh_config: Path | None = ZenohConfigOption,
        status_file: Path | None = typer.Option(
            None,
            "--status-file",
            help="Draw from this local status file (written by `fleet world --status-file`) "
            "instead of asking the control plane.",
        ),
        config: Path | None = typer.Option(
            None, "--config", help="world.yaml to take the obstacles from (default: those the world reports)."
        ),
    ) -> None:
        """Draw a top-down picture of the world now: obstacles, robots, trails and lidar hits.

        By default the world's state comes over the control plane from the agent running it.
        """
        if output.suffix.lower() != ".png":
            raise FleetError("the picture is a PNG: give -o a name ending in .png", Location(output))
        if not output.parent.is_dir():
            raise FleetError("no such directory to write the picture in", Location(output))
        if status_file is not None and (fleet or connect or zenoh_config):
            raise FleetError(
                "--status-file reads a local file: it does not go with --fleet, --connect or --zenoh-config"
            )
        document = _local_world(status_file) if status_file is not None else _remote_world(fleet, connect, zenoh_config)
        from fleet.world.snapshot import draw_snapshot
        from fleet.world.status import obstacle_dict

        obstacles = None
        if config is not None:
            from fleet.world.description import load_world

            obstacles = [obstacle_dict(o) for o in load_world(config).obstacles]
        try:
            draw_snapshot(document.model_dump(exclude_none=True), output, obstacles=obstacles)
        except OSError as error:  # -o names a directory, a read-only place, ...
            raise FleetError(f"cannot write the picture: {error.strerror}", Location(output)) from None
        typer.echo(f"wrote {output}")


def _local_world(status_file: Path):
    from fleet.wire.protocol import world_document
    from fleet.world.status import read_status

    data = read_status(status_file)
    if data is None:
        raise FleetError(
            "no readable world status here (is `fleet world --status-file` running?)", Location(status_file)
        )
    try:
        return world_document(data)
    except ValueError as error:
        raise FleetError(f"not a world status file: {error}", Location(status_file)) from None


def _remote_world(fleet: str | None, connect: str | None, zenoh_config: Path | None):
    """One status query finds the agent running the world; that agent sends the whole state."""
    import time

    from fleet.client import fleet_status
    from fleet.plan import build_view, locate_world

    with client(connect, zenoh_config) as control:  # a fleet unknown here is bad input
        fleet_name, agent = locate_world(build_view(*fleet_status(control, fleet), time.time()), fleet)
        return control.world(fleet_name, agent).world
