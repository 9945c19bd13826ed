"""Control-plane commands: router, agent, up, down, deploy, diff, status, logs, param.

Zenoh and the control package are imported inside the command bodies (fast `fleet --help`).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import typer

if TYPE_CHECKING:
    from rich.progress import TaskID

    from fleet.control.client import ControlClient

CONNECT_HELP = "Router endpoint to connect to (default: $FLEET_CONNECT or tcp/127.0.0.1:7447)."
ZENOH_CONFIG_HELP = "Zenoh JSON5 config file for TLS, user/password or access control (or $FLEET_ZENOH_CONFIG)."
SET_HELP = "Override a parameter: ROBOT.NODE.PARAM=VALUE (value parsed as YAML; repeatable)."

ConnectOption = typer.Option(None, "--connect", "-c", help=CONNECT_HELP)
ZenohConfigOption = typer.Option(None, "--zenoh-config", help=ZENOH_CONFIG_HELP)


def register(app: typer.Typer) -> None:
    app.command("router")(router)
    app.command("agent")(agent)
    app.command("up")(up)
    app.command("down")(down)
    app.command("deploy")(deploy)
    app.command("diff")(diff)
    app.command("status")(status)
    app.command("ros-env")(ros_env)
    app.command("logs")(logs)
    param_app = typer.Typer(help="Read or change a node's ROS parameter live, through its agent.", no_args_is_help=True)
    param_app.command("get")(param_get)
    param_app.command("set")(param_set)
    app.add_typer(param_app, name="param")


# ---------------------------------------------------------------------------------------------
# Helpers


def _endpoints(connect: str | None) -> list[str]:
    from fleet.control.session import default_endpoint

    return [connect or default_endpoint()]


def _zenoh_config(path: Path | None) -> Path | None:
    from fleet.control.session import config_file

    return config_file(path)


def _client(connect: str | None, zenoh_config: Path | None) -> ControlClient:
    from fleet.control.client import ControlClient

    return ControlClient(_endpoints(connect), _zenoh_config(zenoh_config))


def _expand(spec: Path, sets: list[str]):
    """Validate and expand first: a bad spec raises here, before anything is sent."""
    from fleet.cli.render_cmd import load_and_expand

    return load_and_expand(spec, sets)


def _logging() -> None:
    import logging

    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(name)s %(levelname)s %(message)s", stream=sys.stderr)


def _stop_on_signals():
    """An event set by SIGINT or SIGTERM: daemons finish cleanly (stop robots, close sessions)."""
    import signal
    import threading

    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    return stop


# ---------------------------------------------------------------------------------------------
# Daemons


def router(
    listen: list[str] = typer.Option(
        [], "--listen", "-l", help="Endpoint to listen on (repeatable; default tcp/127.0.0.1:7447)."
    ),
    zenoh_config: Path | None = ZenohConfigOption,
    state_dir: Path | None = typer.Option(None, "--state-dir", help="Keep the registry (what runs where) here."),
) -> None:
    """Run a Zenoh router for fleet agents and CLIs (foreground)."""
    from fleet.control.router import run_router
    from fleet.control.session import DEFAULT_ENDPOINT

    _logging()
    endpoints = listen or ([] if _zenoh_config(zenoh_config) else [DEFAULT_ENDPOINT])
    run_router(endpoints, _zenoh_config(zenoh_config), state_dir, _stop_on_signals())


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
    from fleet.control.agent import Agent
    from fleet.control.daemon import state_dir as default_state_dir
    from fleet.control.protocol import address_problem, key_name_problem
    from fleet.errors import FleetError, Location

    if problem := key_name_problem(name):
        raise FleetError(f"agent name {problem}", Location("--name"))
    if address is not None and (problem := address_problem(address)):
        raise FleetError(problem, Location("--address"))
    _logging()
    directory = state_dir or default_state_dir() / "agents" / name
    try:
        daemon = Agent(name, _endpoints(connect), directory, _zenoh_config(zenoh_config), address)
    except ValueError as error:
        raise FleetError(str(error)) from None
    daemon.stop_event = _stop_on_signals()
    daemon.run()


def up(
    listen: str | None = typer.Option(
        None, "--listen", "-l", help="Endpoint (default: $FLEET_CONNECT or tcp/127.0.0.1:7447)."
    ),
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Start the local background daemon (router + agent `local`); state in $FLEET_STATE_DIR."""
    from fleet.control import daemon

    endpoint = _endpoints(listen)[0]
    pid = daemon.start(endpoint, _zenoh_config(zenoh_config))
    typer.echo(f"fleet daemon running (pid {pid}) on {endpoint}; state in {daemon.state_dir()}")


def down(
    spec: Path | None = typer.Argument(None, help="Fleet spec whose fleet to stop."),
    fleet: str | None = typer.Option(None, "--fleet", "-f", help="Name of the fleet to stop."),
    all_: bool = typer.Option(False, "--all", help="Stop every fleet, then the local daemon."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Stop a fleet's robots on every agent (`--all`: every fleet and the local daemon)."""
    from fleet.control import daemon
    from fleet.control import deploy as deploying
    from fleet.errors import ControlError, FleetError

    if spec is not None:
        from fleet.spec import load_spec

        fleet = load_spec(spec).fleet
    if fleet is None and not all_:
        raise FleetError("say which fleet: fleet down SPEC, --fleet NAME, or --all")
    failed = False
    try:
        with _client(connect, zenoh_config) as client:
            if all_:
                statuses, registries = client.status(None)
                fleets = sorted({s.fleet for s in statuses if s.fleet} | {r.fleet for r in registries})
            else:
                assert fleet is not None  # refused above unless --all
                fleets = [fleet]
            for name in fleets:
                replies = deploying.down(client, name)
                for agent_name, reply in sorted(replies.items()):
                    if isinstance(reply, ControlError):
                        failed = True
                        typer.echo(f"{name}: {agent_name}: {reply}", err=True)
                typer.echo(f"fleet {name}: stopped on {len(replies)} agent(s)")
    except ControlError as error:
        if not all_:
            raise
        typer.echo(f"no router: {error}", err=True)
    if all_ and daemon.stop():
        typer.echo("local daemon stopped")
    if failed:
        raise typer.Exit(1)


# ---------------------------------------------------------------------------------------------
# Deploy and diff


def deploy(
    spec: Path = typer.Argument(..., help="Fleet spec file, e.g. fleets/two_robots.yaml."),
    set_: list[str] = typer.Option([], "--set", help=SET_HELP),
    wait: bool = typer.Option(True, "--wait/--no-wait", help="Wait until every robot's nodes run."),
    timeout: float = typer.Option(60.0, "--timeout", help="Seconds to wait for the fleet to come up."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
    json: bool = typer.Option(False, "--json", help="Print the outcome as JSON."),
    dry_run: bool = typer.Option(False, "--dry-run", help="Only show what would be deployed; send nothing."),
) -> None:
    """Send each agent its robots' launch descriptions, wait until they run, show the status."""
    from fleet.cli.output import console, print_json
    from fleet.control import deploy as deploying

    expansion = _expand(spec, set_)
    if dry_run:
        from fleet.cli.plan_view import plan_data, print_plan

        print_json(plan_data(expansion)) if json else print_plan(expansion, console())
        return
    client = _connect_or_start_daemon(expansion, connect, zenoh_config)
    with client:
        progress = _DeployProgress(console(stderr=True), enabled=not json and sys.stderr.isatty())
        with progress:
            outcome = deploying.deploy(client, expansion, wait=wait, timeout=timeout, on_progress=progress.update)
    if json:
        print_json(_outcome_json(outcome))
    else:
        _print_outcome(outcome, console())
    if not outcome.ok and (wait or outcome.unreachable or outcome.refused or outcome.superseded_by):
        raise typer.Exit(1)


def _connect_or_start_daemon(expansion, connect: str | None, zenoh_config: Path | None):
    """Connect; if nothing answers on the default endpoint (a loopback one, not an explicit
    --connect) and the spec places robots on `local`, start the local daemon there first."""
    from fleet.control import daemon
    from fleet.errors import ControlError

    try:
        return _client(connect, zenoh_config)
    except ControlError:
        endpoint = _endpoints(None)[0]
        on_loopback = any(host in endpoint for host in ("/127.0.0.1:", "/localhost:", "/[::1]:"))
        if connect is not None or not on_loopback or not expansion.for_agent(daemon.LOCAL_AGENT):
            raise
    typer.echo(f"starting the local fleet daemon on {endpoint} (state in {daemon.state_dir()})", err=True)
    daemon.start(endpoint, _zenoh_config(zenoh_config))
    return _client(None, zenoh_config)


class _DeployProgress:
    """One rich progress bar per robot: nodes running out of nodes total."""

    def __init__(self, console, enabled: bool):
        self.enabled = enabled
        self.tasks: dict[str, TaskID] = {}
        self.progress = None
        if enabled:
            from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

            self.progress = Progress(
                TextColumn("{task.description:<16}"),
                BarColumn(),
                MofNCompleteColumn(),
                TextColumn("{task.fields[state]}"),
                TimeElapsedColumn(),
                console=console,
                transient=True,
            )

    def __enter__(self):
        if self.progress is not None:
            self.progress.start()
        return self

    def __exit__(self, *exc):
        if self.progress is not None:
            self.progress.stop()

    def update(self, robots) -> None:
        if self.progress is None:
            return
        for robot in robots:
            if robot.name not in self.tasks:
                self.tasks[robot.name] = self.progress.add_task(robot.name, total=max(robot.total, 1), state="")
            self.progress.update(
                self.tasks[robot.name], total=max(robot.total, 1), completed=robot.running, state=robot.state
            )


def _outcome_json(outcome) -> dict:
    from fleet.control import protocol as p

    replies = {}
    for agent_name, reply in outcome.replies.items():
        if isinstance(reply, p.ApplyReply):
            replies[agent_name] = reply.model_dump()
        else:
            replies[agent_name] = {"error": str(reply)}
    return {
        "ok": outcome.ok,
        "generation": outcome.generation,
        "nothing_changed": outcome.nothing_changed,
        "superseded_by": outcome.superseded_by,
        "timed_out": outcome.timed_out,
        "discovery": None
        if outcome.discovery is None
        else {"host": outcome.discovery.host, "server": outcome.discovery.server, "note": outcome.discovery.note},
        "agents": replies,
        "status": outcome.view.to_json() if outcome.view else None,
    }


def _print_outcome(outcome, out) -> None:
    from fleet.control import protocol as p

    for agent_name, reply in sorted(outcome.replies.items()):
        if not isinstance(reply, p.ApplyReply):
            out.print(f"[red]agent {agent_name}: unreachable[/red] ({reply}); its robots stay pending")
        elif not reply.accepted:
            out.print(f"[red]agent {agent_name} refused generation {reply.generation}:[/red] {reply.reason}")
        elif not reply.changes.nothing:
            c = reply.changes
            parts = [
                f"{label} {', '.join(names)}"
                for label, names in (
                    ("started", c.start),
                    ("restarted", c.restart),
                    ("hot-updated", c.hot_update),
                    ("stopped", c.stop),
                    ("unchanged", c.unchanged),
                )
                if names
            ]
            out.print(f"agent {agent_name}: " + "; ".join(parts))
    if outcome.nothing_changed:
        out.print("nothing changed: every robot was already running this description (no restarts)")
    if outcome.superseded_by:
        out.print(f"[yellow]superseded:[/yellow] a later deploy (generation {outcome.superseded_by}) won")
    if outcome.view is not None:
        _print_view(outcome.view, out, agents=False)
    if outcome.discovery is not None and outcome.discovery.note:
        out.print(f"[yellow]note:[/yellow] {outcome.discovery.note}")
    if outcome.timed_out:
        stuck = [row for row in (outcome.view.robots if outcome.view else []) if row.state != "running"]
        out.print(
            "[red]timed out[/red] waiting for every robot to run; not running: "
            + "; ".join(f"{row.name} {row.state}" + (f" ({row.reason})" if row.reason else "") for row in stuck)
        )
    elif outcome.ok:
        out.print("[green]fleet up[/green]")


def diff(
    spec: Path = typer.Argument(..., help="Fleet spec file."),
    set_: list[str] = typer.Option([], "--set", help=SET_HELP),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
    json: bool = typer.Option(False, "--json"),
) -> None:
    """Show what `fleet deploy SPEC` would change, robot by robot."""
    from dataclasses import asdict

    from fleet.cli.output import console, print_json
    from fleet.control import deploy as deploying
    from fleet.control.view import build_view

    expansion = _expand(spec, set_)
    with _client(connect, zenoh_config) as client:
        statuses, registries = client.status(expansion.fleet)
    rows = deploying.diff(expansion, build_view(statuses, registries, time.time()))
    if json:
        print_json([asdict(row) for row in rows])
        return
    from fleet.cli.output import table as make_table

    colours = {"start": "green", "stop": "red", "restart": "yellow", "move": "yellow", "hot-update": "cyan"}
    table = make_table("robot", "agent", "change", "detail", title=f"fleet {expansion.fleet}: deploy would")
    for row in rows:
        colour = colours.get(row.change)
        change = f"[{colour}]{row.change}[/{colour}]" if colour else row.change
        table.add_row(row.robot, row.agent, change, row.detail)
    console().print(table)


# ---------------------------------------------------------------------------------------------
# Status


def status(
    fleet: str | None = typer.Option(None, "--fleet", "-f", help="Only this fleet."),
    json: bool = typer.Option(False, "--json", help="Print JSON."),
    watch: bool = typer.Option(False, "--watch", "-w", help="Refresh every second until Ctrl-C."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Agents (online/offline), robots (state, nodes, restarts, pose, battery) and worlds
    (sim time, real-time factor, contacts) of every fleet."""
    from fleet.cli.output import console, print_json
    from fleet.control.view import build_view

    with _client(connect, zenoh_config) as client:
        if watch and not json:
            from rich.console import Group
            from rich.live import Live

            out = console()
            with Live(console=out, auto_refresh=False) as live:
                try:
                    while True:
                        view = build_view(*client.status(fleet), time.time())
                        live.update(Group(*_view_tables(view)), refresh=True)
                        time.sleep(1.0)
                except KeyboardInterrupt:
                    pass
            return
        view = build_view(*client.status(fleet), time.time())
    if json:
        print_json(view.to_json())
    else:
        _print_view(view, console())
    if not view.all_running:
        raise typer.Exit(1)


def ros_env(
    fleet: str | None = typer.Option(None, "--fleet", "-f", help="The fleet (needed when several run)."),
    agent: str | None = typer.Option(None, "--agent", "-a", help="zenoh transport: the agent on this computer."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print the environment that lets ROS tools (ros2 topic, rviz2) see a fleet's whole graph:
    `eval "$(fleet ros-env)"`."""
    from fleet.control.view import build_view

    with _client(connect, zenoh_config) as client:
        view = build_view(*client.status(fleet), time.time())
    env = tool_environment(view, fleet, agent)
    typer.echo("export " + " ".join(f"{key}={value}" for key, value in env.items()))


def tool_environment(view, fleet: str | None, agent: str | None) -> dict[str, str]:
    """ROS_DOMAIN_ID, ROS_DISCOVERY_SERVER (the fleet's server; with the zenoh transport the one of
    `agent`, whose computer this must be) and ROS_SUPER_CLIENT: a plain client would see only the
    topics it uses itself.  One clear error when the fleet or the server is ambiguous (pure)."""
    from fleet.errors import ControlError, FleetError

    fleets = sorted(view.domain_ids)
    if fleet is None:
        if len(fleets) != 1:
            raise FleetError(
                "no fleet is deployed"
                if not fleets
                else f"several fleets run ({', '.join(fleets)}): pick one with --fleet"
            )
        fleet = fleets[0]
    if fleet not in view.domain_ids:
        raise ControlError(f"fleet {fleet} is not deployed (see `fleet status`)")
    servers = {server["agent"]: server["server"] for server in view.discovery.get(fleet, [])}
    if agent is not None:
        if agent not in servers:
            raise FleetError(
                f"agent {agent} runs no discovery server of fleet {fleet} "
                f"(those that do: {', '.join(sorted(servers)) or 'none'})"
            )
        server = servers[agent]
    elif len(servers) == 1:
        server = next(iter(servers.values()))
    elif not servers:
        raise ControlError(f"no discovery server of fleet {fleet} answers (is its world's agent online?)")
    else:
        raise FleetError(
            f"fleet {fleet} uses the zenoh transport: every computer has its own DDS; "
            f"pick the agent on this one with --agent ({', '.join(sorted(servers))})"
        )
    return {
        "ROS_DOMAIN_ID": str(view.domain_ids[fleet]),
        "ROS_DISCOVERY_SERVER": server,
        "ROS_SUPER_CLIENT": "TRUE",
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
    }


def _print_view(view, out, agents: bool = True) -> None:
    for table in _view_tables(view, agents):
        out.print(table)


def _view_tables(view, agents: bool = True):
    from rich.text import Text

    from fleet.cli.output import table as make_table

    tables = []
    if agents:
        table = make_table(
            "agent", "state", "last seen", "host", "address", "cores", "backends", "fleets", title="Agents"
        )
        for row in view.agents:
            state = "[green]online[/green]" if row.online else "[red]offline[/red]"
            seen = "now" if row.online else (_ago(row.last_seen) if row.last_seen is not None else "never")
            table.add_row(
                row.name,
                state,
                seen,
                row.hostname,
                row.address,
                str(row.cores or ""),
                ", ".join(row.backends),
                ", ".join(row.fleets),
            )
        tables.append(table)
    several_fleets = len({row.fleet for row in view.robots}) > 1
    columns = ["robot", "agent", "state", "nodes", "restarts", "deployed", "pose x,y,yaw", "battery"]
    # Why a robot is not running, where one is not: the column only when there is something to say.
    reasons = any(row.reason and not row.error for row in view.robots)
    if reasons:
        columns.append("reason")
    table = make_table(*(["fleet", *columns] if several_fleets else columns), title="Robots")
    colours = {"running": "green", "starting": "yellow", "pending": "yellow", "degraded": "yellow"}
    for row in view.robots:
        colour = colours.get(row.state, "red")
        pose = f"{row.pose.get('x', 0):.2f},{row.pose.get('y', 0):.2f},{row.pose.get('yaw', 0):.2f}" if row.pose else ""
        battery = f"{row.battery * 100:.0f}%" if row.battery is not None else ""
        state = f"[{colour}]{row.state}[/{colour}]" + (" (live overrides)" if row.overrides else "")
        cells = [
            row.name,
            row.agent,
            state,
            f"{row.running}/{row.total}",
            str(row.restarts),
            _generation_time(row.generation),
            pose,
            battery,
        ]
        if reasons:
            cells.append("" if row.error else row.reason)
        table.add_row(*([row.fleet, *cells] if several_fleets else cells))
    tables.append(table)
    for world in view.worlds:
        tables.append(_world_line(world))
    for row in view.robots:
        if row.error:
            tables.append(Text(f"{row.fleet}/{row.name} on {row.agent}: {row.error}", style="red"))
    return tables


def _world_line(world):
    """One line per world: sim time, real-time factor, contacts (with the latest), problems."""
    from rich.text import Text

    from fleet.control.view import WORLD_SILENT

    line = Text(
        f"world {world.fleet} on {world.agent}: t {world.sim_time:.1f} s, "
        f"RTF {world.real_time_factor:.2f}, {world.robots} robots, "
    )
    count = world.contacts.get("count", 0)
    contacts = f"{count} contact" + ("" if count == 1 else "s")
    last = world.contacts.get("last") or []
    if last:
        contacts += f" (last {last[-1]['a']}-{last[-1]['b']} at {last[-1]['sim_time']:.1f} s)"
    line.append(contacts, style="yellow" if count else None)
    if world.age is not None and world.age > WORLD_SILENT:
        line.append(f"; no report for {world.age:.0f} s (not advancing)", style="red")
    if world.errors:
        more = f" (+{len(world.errors) - 1} more)" if len(world.errors) > 1 else ""
        line.append(f"; error: {world.errors[0]['message']}{more}", style="red")
    return line


def _ago(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.0f} s ago"
    if seconds < 3600:
        return f"{seconds / 60:.0f} min ago"
    return f"{seconds / 3600:.1f} h ago"


def _generation_time(generation: int) -> str:
    """Generations are deploy times in ns: show them as a time of day."""
    if generation <= 0:
        return ""
    return time.strftime("%H:%M:%S", time.localtime(generation / 1e9))


# ---------------------------------------------------------------------------------------------
# Logs and parameters


def _locate(client: ControlClient, robot: str, fleet: str | None) -> tuple[str, str]:
    """(fleet, agent) running `robot`, from one status query."""
    from fleet.control.view import build_view
    from fleet.errors import ControlError, FleetError

    view = build_view(*client.status(fleet), time.time())
    rows = [row for row in view.find_robot(robot, fleet) if row.state not in ("pending", "offline")]
    if not rows:
        raise ControlError(f"no running robot named {robot!r}" + (f" in fleet {fleet}" if fleet else ""))
    if len(rows) > 1:
        raise FleetError(f"robot {robot!r} exists in fleets {', '.join(r.fleet for r in rows)}: pick one with --fleet")
    return rows[0].fleet, rows[0].agent


def logs(
    robot: str = typer.Argument(..., help="Robot name (or `world`)."),
    node: str | None = typer.Argument(None, help="Node name (default: every node of the robot)."),
    follow: bool = typer.Option(False, "--follow", "-f", help="Keep printing new lines until Ctrl-C."),
    tail: int = typer.Option(50, "--tail", "-n", help="Lines to show first (per node)."),
    fleet: str | None = typer.Option(None, "--fleet", help="Fleet of the robot, when several have it."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print a robot's node logs, streamed from its agent."""
    from fleet.control import protocol as p

    with _client(connect, zenoh_config) as client:
        fleet_name, agent_name = _locate(client, robot, fleet)
        cursor = None
        try:
            while True:
                request = p.LogsRequest(fleet=fleet_name, robot=robot, node=node, tail=tail, cursor=cursor)
                reply = client.request(p.logs_key(fleet_name, agent_name), request, p.LogsReply, f"agent {agent_name}")
                nodes = {line.node for line in reply.lines}
                for line in reply.lines:
                    prefix = f"[{line.node}] " if node is None and len(nodes) > 1 else ""
                    sys.stdout.write(f"{prefix}{line.text}\n")
                sys.stdout.flush()
                if not follow:
                    break
                cursor = reply.cursor
                time.sleep(0.5)
        except KeyboardInterrupt:
            pass


def _parse_value(text: str):
    """VALUE as YAML, like `ros2 param set`: 0.8, true, [1.0, 2.0], hello."""
    from fleet.errors import FleetError, Location
    from fleet.spec.yaml_source import parse_scalar

    try:
        return parse_scalar(text)
    except ValueError as error:
        raise FleetError(f"cannot parse value: {error}", Location(f"VALUE {text}")) from None


def _param(robot: str, node: str, name: str, op: Literal["get", "set"], value, fleet, connect, zenoh_config):
    from fleet.control import protocol as p
    from fleet.errors import FleetError

    with _client(connect, zenoh_config) as client:
        fleet_name, agent_name = _locate(client, robot, fleet)
        try:
            request = p.ParamRequest(fleet=fleet_name, robot=robot, node=node, name=name, op=op, value=value)
        except Exception as error:
            raise FleetError(f"invalid parameter request: {error}") from None
        from fleet.control.agent import PARAM_TIMEOUT

        return client.request(
            p.param_key(fleet_name, agent_name), request, p.ParamReply, f"agent {agent_name}", timeout=PARAM_TIMEOUT + 5
        )  # the agent's own wait, plus the round trip


def param_get(
    robot: str = typer.Argument(...),
    node: str = typer.Argument(...),
    name: str = typer.Argument(...),
    fleet: str | None = typer.Option(None, "--fleet"),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Print the current value of a node's parameter."""
    import json

    reply = _param(robot, node, name, "get", None, fleet, connect, zenoh_config)
    if not reply.ok:
        from fleet.errors import error_line

        typer.echo(error_line(reply.reason), err=True)
        raise typer.Exit(1)
    typer.echo(json.dumps(reply.value))


def param_set(
    robot: str = typer.Argument(...),
    node: str = typer.Argument(...),
    name: str = typer.Argument(...),
    value: str = typer.Argument(..., help="New value, as YAML (0.8, true, [1.0, 2.0])."),
    fleet: str | None = typer.Option(None, "--fleet"),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Set a node's parameter live; kept across restarts until the robot's spec changes."""
    reply = _param(robot, node, name, "set", _parse_value(value), fleet, connect, zenoh_config)
    if not reply.ok:
        from fleet.errors import error_line

        typer.echo(error_line(f"{robot}/{node} refused {name}={value}: {reply.reason}"), err=True)
        raise typer.Exit(1)
    typer.echo(f"{robot}/{node}: {name} = {reply.value!r} (recorded on the agent)")
