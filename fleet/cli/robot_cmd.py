"""Commands on one robot, through its agent: logs, param get/set/list."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Literal

import typer

from fleet.cli.options import ConnectOption, ZenohConfigOption, client, fleet_option
from fleet.wire.limits import MAX_LOG_LINES

RobotArgument = typer.Argument(..., help="Robot name (or `world`).")
FleetOfRobotOption = fleet_option("Fleet of the robot, when several have it.")  # -f is `logs --follow`
NodeArgument = typer.Argument(..., help="Node name, as in the robot's launch description.")
ParameterArgument = typer.Argument(..., help="Parameter name (nested ones with dots: limits.turn).")


def register(app: typer.Typer) -> None:
    app.command("logs")(logs)
    param_app = typer.Typer(help="Read or change a node's ROS parameter live, through its agent.", no_args_is_help=True)
    param_app.command("get")(param_get)
    # A negative value (`... max_speed -0.5`) is the value, as with `ros2 param set`, not an option.
    param_app.command("set", context_settings={"ignore_unknown_options": True})(param_set)
    param_app.command("list")(param_list)
    app.add_typer(param_app, name="param")


def logs(
    robot: str = RobotArgument,
    node: str | None = typer.Argument(None, help="Node name (default: every node of the robot)."),
    follow: bool = typer.Option(False, "--follow", "-f", help="Keep printing new lines until Ctrl-C."),
    tail: int = typer.Option(
        50,
        "--tail",
        "-n",
        min=0,
        max=MAX_LOG_LINES,
        help="Lines to show first, per node (nodes sharing a process share its log).",
    ),
    fleet: str | None = FleetOfRobotOption,
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print a robot's node logs, streamed from its agent."""
    from fleet.client import locate_robot
    from fleet.wire import protocol as p

    with client(connect, zenoh_config) as control:
        fleet_name, agent_name = locate_robot(control, robot, fleet)
        cursor = None
        try:
            while True:
                request = p.LogsRequest(fleet=fleet_name, robot=robot, node=node, tail=tail, cursor=cursor)
                reply = control.logs(agent_name, request)
                # Every line of a robot of several nodes says whose it is, as `ros2 launch` prints
                # them; not only those of a reply that happens to hold lines of several (a follower
                # gets one node's new lines at a time).  The cursor names each of its nodes.
                labelled = node is None and len(reply.cursor) > 1
                for line in reply.lines:
                    sys.stdout.write(f"[{line.node}] {line.text}\n" if labelled else f"{line.text}\n")
                sys.stdout.flush()
                if not follow:
                    break
                cursor = reply.cursor
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass


def _parse_value(text: str):
    """VALUE typed as `--set` types it, as rcl reads a parameter file: 0.8, 1e-1, true, [1.0, 2.0], hello."""
    from fleet.errors import FleetError, Location
    from fleet.spec.params import command_line_value

    try:
        return command_line_value(text)
    except ValueError as error:
        raise FleetError(str(error), Location(f"VALUE {text}")) from None


def _param(robot: str, node: str, name: str, op: Literal["get", "set", "list"], value, fleet, connect, zenoh_config):
    from pydantic import ValidationError

    from fleet.client import locate_robot
    from fleet.errors import COMMAND_LINE, FleetError, Location
    from fleet.wire import protocol as p

    try:  # checked before connecting: bad input is refused before anything is asked
        request = p.ParamRequest(fleet="", robot=robot, node=node, name=name, op=op, value=value)
    except ValidationError as error:
        problem = p.short_validation_error(error)
        raise FleetError(f"invalid parameter request: {problem}", Location(COMMAND_LINE)) from None
    with client(connect, zenoh_config) as control:
        fleet_name, agent_name = locate_robot(control, robot, fleet)  # the request's fleet is the robot's
        return control.param(agent_name, request.model_copy(update={"fleet": fleet_name}))


def _shown(value) -> str:
    """A parameter's value as ROS YAML writes it (true, 0.5, [1.0, 2.0]); None is what the agent
    sends for a type fleet does not carry."""
    from fleet.spec.rcl_types import value_text

    return "(not shown: a byte array)" if value is None else value_text(value)


def param_get(
    robot: str = RobotArgument,
    node: str = NodeArgument,
    name: str = ParameterArgument,
    fleet: str | None = FleetOfRobotOption,
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print the current value of a node's parameter."""
    reply = _param(robot, node, name, "get", None, fleet, connect, zenoh_config)
    if not reply.ok:
        from fleet.errors import error_line

        typer.echo(error_line(reply.reason), err=True)
        raise typer.Exit(1)
    typer.echo(_shown(reply.value))


def param_set(
    robot: str = RobotArgument,
    node: str = NodeArgument,
    name: str = ParameterArgument,
    value: str = typer.Argument(..., help="New value, typed as --set types it (0.8, 1e-1, true, [1.0, 2.0])."),
    fleet: str | None = FleetOfRobotOption,
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Set a node's parameter live; kept across restarts until the robot's spec changes."""
    new = _parse_value(value)
    reply = _param(robot, node, name, "set", new, fleet, connect, zenoh_config)
    if not reply.ok:
        from fleet.errors import EXIT_USAGE, error_line
        from fleet.wire.protocol import REFUSED

        if reply.code == REFUSED:  # the node answered no: the value given is bad input
            typer.echo(error_line(f"{robot}/{node} refused {name}={_shown(new)}: {reply.reason}"), err=True)
            raise typer.Exit(EXIT_USAGE)
        typer.echo(error_line(reply.reason), err=True)  # no answer: the node is not running, say
        raise typer.Exit(1)
    kept = reply.note or "recorded on the agent"  # the note: why it is not kept across restarts
    typer.echo(f"{robot}/{node}: {name} = {_shown(reply.value)} ({kept})")


def param_list(
    robot: str = RobotArgument,
    node: str | None = typer.Argument(None, help="One node of the robot (default: every node)."),
    fleet: str | None = FleetOfRobotOption,
    json: bool = typer.Option(False, "--json", help="Print {node: {parameter: value}} and what was set live."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print every parameter of a robot's nodes as they are now (like `ros2 param dump`)."""
    from fleet.cli.output import console, print_json, table
    from fleet.errors import error_line

    reply = _param(robot, node or "", "", "list", None, fleet, connect, zenoh_config)
    if not reply.ok:
        typer.echo(error_line(f"{robot}: {reply.reason}"), err=True)
        raise typer.Exit(1)
    if json:
        print_json(
            {"robot": robot, "parameters": reply.parameters, "set_live": reply.set_live, "unanswered": reply.unanswered}
        )
    elif reply.parameters:  # none when every node asked for is unanswered: the errors alone say so
        rows = table("node", "parameter", "value", "set live", title=f"Parameters of {robot}")
        for node_name, values in sorted(reply.parameters.items()):
            live = set(reply.set_live.get(node_name, []))
            for name, value in values.items():
                rows.add_row(node_name, name, _shown(value), "yes" if name in live else "")
        console().print(rows)
    if reply.unanswered:
        # One line for the nodes that did not answer for one reason (those of a process that is
        # not running): `robot2/controller+battery: not running (...)`, as `fleet logs` labels them.
        silent: dict[str, list[str]] = {}
        for node_name, why in reply.unanswered.items():  # in the robot's order of its nodes
            silent.setdefault(why, []).append(node_name)
        for why, names in silent.items():
            typer.echo(error_line(f"{robot}/{'+'.join(names)}: {why}"), err=True)
        raise typer.Exit(1)
