"""Every command's --fleet is a fleet name, checked before anything is asked of the fleet: a Zenoh
wildcard or special character in it would make an invalid key (a traceback) or match every fleet."""

from __future__ import annotations

import pytest
from typer.main import get_command

from fleet.cli import app
from tests.cli.test_error_line import one_error_line


def commands_with_fleet_option() -> list[list[str]]:
    """The command line of every command that takes --fleet, with its required arguments filled in."""
    found = []

    def walk(command, path: list[str]) -> None:
        if hasattr(command, "commands"):  # a group (typer may vendor its own click: no isinstance)
            for name, sub in command.commands.items():
                walk(sub, [*path, name])
        elif any("--fleet" in param.opts for param in command.params):
            arguments = [param for param in command.params if param.param_type_name == "argument" and param.required]
            found.append([*path, *["x"] * len(arguments)])

    walk(get_command(app), [])
    return found


COMMANDS = commands_with_fleet_option()


def test_the_commands_that_take_a_fleet_are_found():
    names = {" ".join(word for word in command if word != "x") for command in COMMANDS}
    assert {"status", "ros-env", "down", "logs", "param get", "param set", "param list", "snapshot"} <= names


@pytest.mark.parametrize("name", ["two_*", "*", "a$b", "a#b", "a/b", "**"])
@pytest.mark.parametrize("command", COMMANDS, ids=" ".join)
def test_a_fleet_name_that_is_not_one_is_bad_input(capsys, monkeypatch, command, name):
    def no_connection(*args, **kwargs):
        raise AssertionError("a bad --fleet must be refused before connecting")

    monkeypatch.setattr("fleet.client.connect", no_connection)
    monkeypatch.setattr("fleet.client.local_daemon.connect_or_start", no_connection)
    line = one_error_line(capsys, [*command, "--fleet", name])
    assert line.startswith(f"fleet: error: <command line>: --fleet: {name!r} is not a valid name"), line
