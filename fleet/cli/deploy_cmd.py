"""Deploying commands: deploy, diff, down, restart.

The work is fleet.client's (deploy, down, restart) and fleet.plan's (diff); here: options and output.
"""

from __future__ import annotations

import os
import sys
import time
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from fleet.cli.options import SET_HELP, ConnectOption, ZenohConfigOption, client, fleet_option, note_waiting

if TYPE_CHECKING:
    from rich.progress import TaskID

    from fleet.plan.diff import DiffRow


def register(app: typer.Typer) -> None:
    app.command("down")(down)
    app.command("deploy")(deploy)
    app.command("diff")(diff)
    app.command("restart")(restart)


def down(
    spec: Path | None = typer.Argument(None, help="Fleet spec whose fleet to stop."),
    fleet: str | None = fleet_option("Name of the fleet to stop.", "-f"),
    all_: bool = typer.Option(False, "--all", help="Stop every fleet, then the local daemon."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
) -> None:
    """Stop a fleet's robots on every agent (`--all`: every fleet and the local daemon)."""
    from fleet.client import down as stop_fleet
    from fleet.client import local_daemon
    from fleet.errors import ControlError, FleetError
    from fleet.plan import known_fleets

    if spec is not None:
        from fleet.spec import load_spec

        fleet = load_spec(spec).fleet
    if fleet is None and not all_:
        raise FleetError("say which fleet: fleet down SPEC, --fleet NAME, or --all")
    failed = False
    if all_ and connect is None and (found := local_daemon.elsewhere(None)):
        connect = found[1]  # `--all` means the local daemon's fleets too, wherever it listens
    try:
        with client(connect, zenoh_config) as control:
            if all_:
                fleets = known_fleets(*control.status(None))
            else:
                assert fleet is not None  # refused above unless --all
                fleets = [fleet]
            for name in fleets:
                replies = stop_fleet(control, name)
                stopped = 0
                for agent_name, reply in sorted(replies.items()):
                    if isinstance(reply, ControlError):
                        typer.echo(f"{name}: {agent_name}: {reply}", err=True)
                    elif not reply.accepted:  # e.g. it holds a later deploy, which goes on running
                        typer.echo(f"{name}: {agent_name}: refused: {reply.reason}", err=True)
                    else:
                        stopped += 1
                of_all = "" if stopped == len(replies) else f" of {len(replies)}"
                failed = failed or bool(of_all)
                typer.echo(f"fleet {name}: stopped on {stopped}{of_all} agent(s)")
    except ControlError as error:
        if not all_:
            raise
        typer.echo(f"no router: {error}", err=True)
    if all_ and local_daemon.stop():
        typer.echo("local daemon stopped")
    if failed:
        raise typer.Exit(1)


def deploy(
    spec: Path = typer.Argument(..., help="Fleet spec file, e.g. fleets/two_robots.yaml."),
    set_: list[str] = typer.Option([], "--set", help=SET_HELP),
    wait: bool = typer.Option(
        True,
        "--wait/--no-wait",
        help="Wait until every robot runs (--no-wait: only until the router holds the deploy).",
    ),
    timeout: float = typer.Option(60.0, "--timeout", min=0, help="Seconds to wait for the fleet to come up."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
    json: bool = typer.Option(False, "--json", help="Print the outcome as JSON."),
    dry_run: bool = typer.Option(
        False,
        "--dry-run",
        help="Only show what would be deployed (as `fleet render`); connect to nothing. "
        "`fleet diff` shows what it would change.",
    ),
) -> None:
    """Send each agent its robots' launch descriptions, wait until they run, show the status."""
    from fleet.cli.output import console, print_json, print_warnings
    from fleet.cli.render_cmd import load_and_expand
    from fleet.client import deploy as deploy_fleet
    from fleet.client.local_daemon import connect_or_start
    from fleet.errors import EXIT_USAGE

    expansion = load_and_expand(spec, set_)  # a bad spec raises here, before anything is sent
    print_warnings(expansion.warnings)
    if dry_run:
        from fleet.cli.plan_view import plan_data, print_plan

        if json:
            print_json(plan_data(expansion))
        else:
            print_plan(expansion, console())
            console().print("dry run: nothing sent (`fleet diff SPEC` shows what a deploy would change)")
        return
    agents = {bundle.agent for bundle in expansion.bundles}
    announce = partial(typer.echo, err=True)
    with connect_or_start(connect, zenoh_config, agents, announce, note_waiting) as control:
        progress = _DeployProgress(console(stderr=True), enabled=not json and sys.stderr.isatty())
        with progress:
            outcome = deploy_fleet(control, expansion, wait=wait, timeout=timeout, on_progress=progress.update)
    if json:
        print_json(outcome.to_json())
    elif outcome.problems:
        _print_problems(outcome.problems, control.connect[0])
    else:
        _print_outcome(outcome, console())
        if outcome.unreachable:
            typer.echo(_start_agents_hint(sorted(outcome.unreachable), control.connect[0]), err=True)
    if outcome.problems:
        raise typer.Exit(EXIT_USAGE)  # the spec's templates name what is not there: bad input
    if not outcome.ok:
        raise typer.Exit(1)


def restart(
    robots: list[str] = typer.Argument(..., help="Robots to restart (or `world`)."),
    fleet: str | None = fleet_option("Fleet of the robots, when several have them.", "-f"),
    wait: bool = typer.Option(True, "--wait/--no-wait", help="Wait until each robot runs again."),
    timeout: float = typer.Option(60.0, "--timeout", min=0, help="Seconds to wait for the robots to run again."),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
    json: bool = typer.Option(False, "--json", help="Print the outcome as JSON."),
) -> None:
    """Stop robots' nodes and start them again as deployed (parameters set live are kept).

    Exits 1 unless they, and their fleet's robots that ran before, run again in time."""
    from fleet.cli.output import console, labelled, print_json
    from fleet.client import restart as restart_robots

    with client(connect, zenoh_config) as control:
        progress = _DeployProgress(console(stderr=True), enabled=not json and sys.stderr.isatty())
        with progress:
            outcome = restart_robots(control, robots, fleet, wait=wait, timeout=timeout, on_progress=progress.update)
    if json:
        print_json(outcome.to_json())
    else:
        out = console()
        for (_fleet, name), (agent, _number) in outcome.asked.items():
            row = outcome.rows.get((_fleet, name))
            if not wait:
                out.print(labelled(f"{name}:", "green", f"restart asked of agent {agent}"))
            elif outcome.back((_fleet, name)):
                out.print(labelled(f"{name}:", "green", f"running again on agent {agent}"))
            else:
                state = "not seen" if row is None else row.state + (f" ({row.reason})" if row.reason else "")
                why = "timed out waiting" if outcome.timed_out else "waiting longer would not help"
                out.print(labelled(f"{name}:", "red", f"{state}: {why}"))
        for row in outcome.others_not_running:
            state = row.state + (f" ({row.reason})" if row.reason else "")
            out.print(labelled(f"{row.name}:", "red", f"ran before the restart, {state} now"))
    if not outcome.ok:
        raise typer.Exit(1)


def _print_problems(problems: dict[str, dict[str, str]], endpoint: str) -> None:
    from fleet.errors import error_line

    for agent_name, robots in sorted(problems.items()):
        for robot, problem in sorted(robots.items()):
            typer.echo(error_line(f"{robot} cannot start on agent {agent_name}: {problem}"), err=True)
    for hint in _daemon_environment_hints(problems, endpoint):
        typer.echo(hint, err=True)
    typer.echo("nothing was deployed: every robot runs as it was", err=True)


def _daemon_environment_hints(problems: dict[str, dict[str, str]], endpoint: str) -> list[str]:
    """For a package the local daemon's agents did not find: they search the AMENT_PREFIX_PATH the
    daemon started with, which a workspace sourced since (`source install/setup.bash`) did not
    change. Says whether this shell's finds it, and how to restart the daemon with it."""
    from fleet.client.local_daemon import agents_reached
    from fleet.runtime.ament import indexes, missing_package

    local = set(agents_reached(endpoint)) & set(problems)
    packages = {
        package for agent in local for problem in problems[agent].values() if (package := missing_package(problem))
    }
    hints = []
    for package in sorted(packages):
        prefix = indexes(package, os.environ.get("AMENT_PREFIX_PATH", ""))
        then = (
            f"this shell's has {package} (in {prefix}): `fleet down --all` (it stops every fleet there), then "
            "deploy again to restart the daemon with this shell's environment"
            if prefix
            else f"this shell's lacks {package} too: source the workspace that installs it, `fleet down --all` "
            "(it stops every fleet there), then deploy again"
        )
        hints.append(f"hint: the local daemon searches the AMENT_PREFIX_PATH it was started with; {then}")
    return hints


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


def _print_outcome(outcome, out) -> None:
    from fleet.cli.output import labelled
    from fleet.cli.status_view import print_view
    from fleet.wire import protocol as p

    for agent_name, reply in sorted(outcome.replies.items()):
        if not isinstance(reply, p.ApplyReply):
            out.print(labelled(f"{reply}:", "red", "its robots stay pending"))  # "agent NAME is unreachable (...)"
        elif not reply.accepted:
            out.print(labelled(f"agent {agent_name} refused generation {reply.generation}:", "red", reply.reason))
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
        out.print(labelled("superseded:", "yellow", f"a later deploy (generation {outcome.superseded_by}) won"))
    if outcome.nothing_changed and outcome.ok and outcome.view is not None:
        # The table would repeat `fleet status` row for row (seconds of output at 1,000 robots).
        robots = [row for row in outcome.view.robots if row.kind == "robot"]
        worlds = len(outcome.view.robots) - len(robots)
        where = f"{len(robots)} robot(s)" + (" and the world" if worlds else "")
        agents = len({row.agent for row in outcome.view.robots})
        out.print(f"{where} running on {agents} agent(s); `fleet status` shows them")
    elif outcome.view is not None:
        print_view(outcome.view, out, agents=False)
    if outcome.discovery is not None and outcome.discovery.note:
        out.print(labelled("note:", "yellow", outcome.discovery.note))
    if outcome.timed_out and not outcome.recorded:
        out.print(labelled("timed out", "red", "the router did not take the deploy within the timeout (see its log)"))
    elif outcome.timed_out:
        out.print(labelled("timed out", "red", f"waiting for every robot to run; not running: {_not_running(outcome)}"))
    elif outcome.ok and outcome.waited:
        out.print(labelled("fleet up", "green"))
    elif outcome.ok:
        out.print(labelled("deploy taken", "green", "(not waiting for the robots: `fleet status` shows them)"))
    elif outcome.waited and not (outcome.unreachable or outcome.refused or outcome.superseded_by):
        out.print(labelled("not up:", "red", f"waiting longer would not help; not running: {_not_running(outcome)}"))


def _start_agents_hint(agents: list[str], endpoint: str) -> str:
    """How to start the agents a deploy could not reach (they may run and be cut off, too): the
    router holds their robots for them until they connect."""
    from fleet.wire.session import endpoint_parts, on_loopback

    if len(agents) == 1:
        which, kept, where, name = f"agent {agents[0]} does", "its robots for it", "start it", agents[0]
    else:
        which, kept, where, name = f"agents {', '.join(agents)} do", "their robots for them", "start each", "NAME"
    lead = f"hint: {which} not answer (the router keeps {kept}); if not running, {where} on its computer:"
    parts = endpoint_parts(endpoint)
    # Over TLS an agent needs its own certificate: the config `fleet certs` made for it.
    certificate = f" --zenoh-config agent-{name}.json5" if parts is not None and parts[0] == "tls" else ""
    if parts is None or not on_loopback(endpoint):
        return f"{lead} `fleet agent --name {name} --connect {endpoint}{certificate}` (docs/multi-computer.md)"
    # The router is this computer's (the local daemon's): other computers reach it at an address
    # of this one, and the local daemon can run the agents here.
    protocol, _, port = parts
    local = " ".join(f"--agent {agent}" for agent in agents)
    return (
        f"{lead} `fleet agent --name {name} --connect {protocol}/ADDRESS:{port}{certificate}` "
        f"(ADDRESS: this computer's, on their network; docs/multi-computer.md), or all on this one: `fleet up {local}`"
    )


def _not_running(outcome) -> str:
    return "; ".join(
        f"{row.name} {row.state}" + (f" ({row.reason})" if row.reason else "") for row in outcome.not_running
    )


def diff(
    spec: Path = typer.Argument(..., help="Fleet spec file."),
    set_: list[str] = typer.Option([], "--set", help=SET_HELP),
    connect: str | None = ConnectOption,
    zenoh_config: Path | None = ZenohConfigOption,
    json: bool = typer.Option(False, "--json"),
) -> None:
    """Show what `fleet deploy SPEC` would change, robot by robot.

    Exits 1 when a deploy would change something (as `kubectl diff`), 0 when every robot already
    runs what the spec says."""
    from dataclasses import asdict

    from fleet.cli.output import print_json, print_warnings
    from fleet.cli.render_cmd import load_and_expand
    from fleet.client import check_domain, visible_statuses
    from fleet.errors import EXIT_FAILURE
    from fleet.plan import build_view, discovery_for
    from fleet.plan import diff as plan_diff

    expansion = load_and_expand(spec, set_)
    print_warnings(expansion.warnings)
    with client(connect, zenoh_config) as control:
        statuses, registries = visible_statuses(control, expansion.fleet)
        deployed = {
            bundle.name: bundle for state in control.desired_states(expansion.fleet) for bundle in state.bundles
        }
    view = build_view(statuses, registries, time.time())
    check_domain(expansion, view)  # deploy would refuse it
    rows = plan_diff(expansion, view, deployed, discovery_for(expansion, view))
    if json:
        print_json([asdict(row) for row in rows])
    else:
        _print_diff(expansion.fleet, rows)
    if any(row.change != "unchanged" for row in rows):
        raise typer.Exit(EXIT_FAILURE)


def _print_diff(fleet: str, rows: list[DiffRow]) -> None:
    from rich.text import Text

    from fleet.cli.output import console
    from fleet.cli.output import table as make_table

    colours = {"start": "green", "stop": "red", "restart": "yellow", "move": "yellow", "hot-update": "cyan"}
    table = make_table("robot", "agent", "change", "detail", title=f"fleet {fleet}: deploy would")
    for row in rows:
        colour = colours.get(row.change)
        change = Text(row.change, style=colour or "")
        table.add_row(row.robot, row.agent, change, row.detail)
    console().print(table)
