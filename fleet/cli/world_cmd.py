"""`fleet world` (run the shared PyBullet world) and `fleet snapshot` (picture of it)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from fleet.errors import FleetError, Location


def register(app: typer.Typer) -> None:
    @app.command("world")
    def world(
        config: Path = typer.Option(..., "--config", help="world.yaml describing obstacles and robots."),
        status_file: Optional[Path] = typer.Option(None, "--status-file", help="Write the world's state here (JSON, atomically, a few times a second); robots restart from the poses in it."),
        as_fast_as_possible: bool = typer.Option(False, "--as-fast-as-possible", help="Do not pace to the wall clock (tests, benchmarks)."),
    ) -> None:
        """Run the shared PyBullet world hosting every simulated robot (until Ctrl-C).

        Robots join and leave as world.yaml changes on disk.
        """
        from fleet.world.description import load_world

        load_world(config)  # fail fast with one line, before pybullet and rclpy load
        from fleet.world.app import run_world

        run_world(config, status_file, as_fast_as_possible=as_fast_as_possible)

    @app.command("snapshot")
    def snapshot(
        status_file: Path = typer.Option(..., "--status-file", help="Status file written by `fleet world --status-file`."),
        config: Optional[Path] = typer.Option(None, "--config", help="world.yaml to take the obstacles from (default: those in the status file)."),
        output: Path = typer.Option(Path("world.png"), "-o", "--output", help="PNG to write."),
    ) -> None:
        """Draw a top-down picture of the world: obstacles, robots, trails and lidar hits."""
        from fleet.world.snapshot import draw_snapshot
        from fleet.world.status import obstacle_dict, read_status

        status = read_status(status_file)
        if status is None:
            raise FleetError("no readable world status here (is `fleet world --status-file` running?)",
                             Location(status_file))
        obstacles = None
        if config is not None:
            from fleet.world.description import load_world

            obstacles = [obstacle_dict(o) for o in load_world(config).obstacles]
        draw_snapshot(status, output, obstacles=obstacles)
        typer.echo(f"wrote {output}")
