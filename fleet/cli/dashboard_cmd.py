"""`fleet dashboard`: the fleet on a local web page, live (fleet.dashboard)."""

from __future__ import annotations

from pathlib import Path

import typer

from fleet.cli.options import ConnectOption, ZenohConfigOption, client, fleet_option


def register(app: typer.Typer) -> None:
    app.command("dashboard")(dashboard)


def dashboard(
    host: str = typer.Option(
        "127.0.0.1",
        "--host",
        help="Address to serve on; other than loopback, other computers see the fleet (no login).",
    ),
    port: int = typer.Option(8080, "--port", "-p", min=0, max=65535, help="Port to serve on; 0 picks a free one."),
    fleet: str | None = fleet_option("Only this fleet.", "-f"),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Serve a live web page of the fleet: world map, agents, robots, logs, parameters, generations."""
    import logging
    import sys

    from fleet.client import fleet_status
    from fleet.dashboard.live import LiveFleet
    from fleet.dashboard.server import listen, serve, url_of

    logging.basicConfig(level=logging.WARNING, format="%(asctime)s %(name)s %(levelname)s %(message)s")
    sock = listen(host, port)  # a port in use is bad input: said before anything else happens
    try:
        with client(connect, zenoh_config) as control:
            fleet_status(control, fleet)  # a fleet unknown here is bad input, not an empty fleet all running
            typer.echo(f"fleet dashboard on {url_of(sock)} (Ctrl-C stops it)")
            sys.stdout.flush()
            serve(LiveFleet(control, fleet), sock)
    finally:
        sock.close()
