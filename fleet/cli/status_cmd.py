"""What runs: `fleet status` and `fleet ros-env`."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from fleet.cli.options import ConnectOption, ZenohConfigOption, client, fleet_option

if TYPE_CHECKING:
    from fleet.client import ControlClient
    from fleet.plan import FleetView


def register(app: typer.Typer) -> None:
    app.command("status")(status)
    app.command("ros-env")(ros_env)


def status(
    robots: list[str] = typer.Argument(
        None, help="Only these robots (or `world`), and a table of their nodes, as `kubectl get pod NAME`."
    ),
    fleet: str | None = fleet_option("Only this fleet.", "-f"),
    json: bool = typer.Option(False, "--json", help="Print JSON."),
    watch: bool = typer.Option(
        False, "--watch", "-w", help="Refresh every second until Ctrl-C (with --json: one document per line each time)."
    ),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Agents, robots and worlds of every fleet, and whether their data flows.

    Agents (online/offline), robots (state, nodes, restarts, pose, battery)
    and worlds (sim time, real-time factor, contacts).  Without --watch,
    exits 1 unless every robot runs."""
    from fleet.cli.output import console, print_json, print_json_line
    from fleet.cli.status_view import print_view, view_tables
    from fleet.client import fleet_status
    from fleet.plan import build_view

    robots = robots or []
    nodes = bool(robots)  # robots named: their nodes too
    with client(connect, zenoh_config) as control:
        view = build_view(*fleet_status(control, fleet), time.time())  # a fleet unknown here ends it now
        if robots:
            from fleet.client.robots import robots_named

            view = robots_named(view, robots, fleet)  # a robot unknown here ends it now
        if watch and json:  # a stream, as `kubectl get -w -o json`: one document per line per refresh
            _refresh(control, fleet, robots, view, lambda view: print_json_line(view.to_json()))
            return
        if watch and not console().is_terminal:
            # Piped (`| tee`, a file): rich would hold a live display until the end; each refresh is
            # printed whole and flushed instead, a blank line between, as `kubectl get -w` streams.
            _refresh(control, fleet, robots, view, lambda view: _print_block(view, console(), nodes))
            return
        if watch:
            from rich.console import Group
            from rich.live import Live

            with Live(console=console(), auto_refresh=False) as live:
                _refresh(
                    control,
                    fleet,
                    robots,
                    view,
                    lambda view: live.update(Group(*view_tables(view, nodes=nodes)), refresh=True),
                )
            return
    if json:
        print_json(view.to_json())
    else:
        print_view(view, console(), nodes=nodes)
    if not view.all_running:
        raise typer.Exit(1)


def _print_block(view: FleetView, out, nodes: bool) -> None:
    from fleet.cli.status_view import print_view

    print_view(view, out, nodes=nodes)
    out.print()
    out.file.flush()


def _refresh(
    control: ControlClient, fleet: str | None, robots: list[str], view: FleetView, show: Callable[[FleetView], None]
) -> None:
    """Show the view, then a new one every second until Ctrl-C; on while the fleet goes down, or
    the router restarts: it shows that.  `robots`: only those (none: every robot)."""
    from fleet.plan import build_view

    try:
        while True:
            show(view)
            time.sleep(1.0)
            view = build_view(*control.status(fleet), time.time())
            if robots:
                view = view.of_robots(robots)
    except KeyboardInterrupt:
        pass


def ros_env(
    fleet: str | None = fleet_option("The fleet (needed when several run).", "-f"),
    agent: str | None = typer.Option(None, "--agent", "-a", help="zenoh transport: the agent on this computer."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print the environment that lets ROS tools see a fleet's whole graph.

    For ros2 topic, ros2 node, rviz2: `eval "$(fleet ros-env)"`."""
    from fleet.client import fleet_status, tool_environment
    from fleet.plan import build_view

    with client(connect, zenoh_config) as control:  # a fleet unknown here is bad input
        view = build_view(*fleet_status(control, fleet), time.time())
    env = tool_environment(view, fleet, agent)
    typer.echo("export " + " ".join(f"{key}={value}" for key, value in env.items()))
