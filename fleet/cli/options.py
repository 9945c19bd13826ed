"""Options shared by several command groups, and the client the commands that talk to a router open."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import typer

if TYPE_CHECKING:
    from fleet.client import ControlClient

CONNECT_HELP = "Router endpoint to connect to (default: $FLEET_CONNECT or tcp/127.0.0.1:7447)."
SET_HELP = "Override a parameter: ROBOT.NODE.PARAM=VALUE (value parsed as YAML; repeatable)."
ZENOH_CONFIG_HELP = "Zenoh JSON5 config file for TLS, user/password or access control (or $FLEET_ZENOH_CONFIG)."

ConnectOption = typer.Option(None, "--connect", "-c", help=CONNECT_HELP)
ZenohConfigOption = typer.Option(None, "--zenoh-config", help=ZENOH_CONFIG_HELP)


def fleet_option(help: str, *short: str) -> Any:
    """The --fleet option of every command that takes one (`short`: its "-f", where that is free)."""
    return typer.Option(None, "--fleet", *short, help=help, callback=_checked_fleet_name)


def _checked_fleet_name(name: str | None) -> str | None:
    """A fleet name becomes a chunk of Zenoh keys: a wildcard (`*`) or `$` in it would match other
    fleets' keys or make an invalid key, so it is refused as bad input before anything is asked."""
    from fleet.errors import FleetError
    from fleet.rules import key_name_problem

    if name is not None and (problem := key_name_problem(name)):
        raise FleetError(f"--fleet: {problem}")
    return name


def client(connect: str | None, zenoh_config: Path | None) -> ControlClient:
    from fleet.client import connect as connect_client
    from fleet.errors import ControlError

    try:
        return connect_client(connect, zenoh_config, note_waiting)
    except ControlError as error:
        from fleet.client.local_daemon import listening_elsewhere

        raise (listening_elsewhere(connect) or error) from None


def note_waiting(line: str) -> None:
    """A long wait of the client's, said on stderr as it starts (the command's output stays clean)."""
    typer.echo(f"note: {line}", err=True)
