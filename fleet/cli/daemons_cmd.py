"""Server commands, in the foreground: router, agent; and `fleet up`, the local daemon."""

from __future__ import annotations

import sys
from pathlib import Path

import typer

from fleet.cli.options import ConnectOption, ZenohConfigOption


def register(app: typer.Typer) -> None:
    app.command("router")(router)
    app.command("agent")(agent)
    app.command("up")(up)


def _logging() -> None:
    import logging

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s", stream=sys.stderr)


def router(
    listen: list[str] = typer.Option(
        [], "--listen", "-l", help="Endpoint to listen on (repeatable; default tcp/127.0.0.1:7447)."
    ),
    zenoh_config: Path | None = ZenohConfigOption,
    state_dir: Path | None = typer.Option(None, "--state-dir", help="Keep the registry (what runs where) here."),
) -> None:
    """Run a Zenoh router for fleet agents and CLIs (foreground)."""
    from fleet.runtime.processes import stop_on_signals
    from fleet.server.router import run_router
    from fleet.wire.session import DEFAULT_ENDPOINT, config_file

    _check_state_dir(state_dir)
    _logging()
    config = config_file(zenoh_config)
    endpoints = listen or ([] if config else [DEFAULT_ENDPOINT])
    run_router(endpoints, config, state_dir, stop_on_signals())


def _check_state_dir(directory: Path | None) -> None:
    """--state-dir names a directory, or a place one can be made."""
    from fleet.errors import FleetError, Location
    from fleet.rules import directory_problem

    if directory is not None and (problem := directory_problem(directory)):
        raise FleetError(f"state directory {problem}", Location(directory))


def agent(
    name: str = typer.Option(..., "--name", "-n", help="Agent name, as robots' `agent:` in fleet specs."),
    connect: str | None = ConnectOption,
    state_dir: Path | None = typer.Option(
        None, "--state-dir", help="Desired state and units (default: <state dir>/agents/NAME)."
    ),
    zenoh_config: Path | None = ZenohConfigOption,
    address: str | None = typer.Option(
        None,
        "--address",
        help="IPv4 address other computers reach this one at (default: the one on the route to the router).",
    ),
) -> None:
    """Run an agent (foreground): receives desired state, runs the robots, reports status."""
    from fleet import rules
    from fleet.errors import FleetError, Location
    from fleet.runtime.processes import stop_on_signals
    from fleet.server.agent import Agent
    from fleet.wire.protocol import address_problem
    from fleet.wire.session import check_identity, config_file, default_endpoint

    if problem := rules.key_name_problem(name):
        raise FleetError(f"agent name {problem}", Location("--name"))
    if address is not None and (problem := address_problem(address)):
        raise FleetError(problem, Location("--address"))
    _check_state_dir(state_dir)
    config = config_file(zenoh_config)
    check_identity(name, config)
    _logging()
    directory = state_dir or rules.agent_dir(rules.state_dir(), name)
    try:
        daemon = Agent(name, [default_endpoint() if connect is None else connect], directory, config, address)
    except ValueError as error:
        raise FleetError(str(error)) from None
    daemon.stop_event = stop_on_signals()
    daemon.run()


def up(
    listen: str | None = typer.Option(
        None,
        "--listen",
        "-l",
        help="Endpoint (default: $FLEET_CONNECT or tcp/127.0.0.1:7447). A daemon running elsewhere is "
        "restarted here, its fleets kept.",
    ),
    zenoh_config: Path | None = ZenohConfigOption,
    agents: list[str] = typer.Option(
        [],
        "--agent",
        "-a",
        help="Also run an agent of this name (repeatable): a spec for several computers on this one. "
        "A daemon running without it is restarted with it, its fleets kept.",
    ),
) -> None:
    """Start the local background daemon (router + agent `local`); state in $FLEET_STATE_DIR."""
    from fleet import rules
    from fleet.client import local_daemon
    from fleet.errors import FleetError, Location
    from fleet.wire.session import config_file, listen_problem

    for name in agents:
        if problem := rules.key_name_problem(name):
            raise FleetError(f"agent name {problem}", Location(f"--agent {name}"))
    if listen is not None and (problem := listen_problem(listen)):
        raise FleetError(problem, Location("--listen"))
    pid = local_daemon.start(
        listen,
        config_file(zenoh_config) if zenoh_config else None,  # without it: as it runs
        agents=agents,
        announce=lambda message: typer.echo(message, err=True),
    )
    running = ", ".join(local_daemon.running_agents(pid))
    endpoint = local_daemon.running_endpoint(pid)
    typer.echo(f"fleet daemon running (pid {pid}) on {endpoint} with agents {running}; state in {rules.state_dir()}")
