"""What a deploy would change: the desired state of an Expansion against the fleet as it runs (pure)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fleet.plan.discovery import DiscoveryPlan
from fleet.plan.parameters import ParameterChange, parameter_changes
from fleet.plan.view import FleetView, RobotRow
from fleet.rules import PARAMS_SUFFIX, SIMULATED_OPTION, WORLD_DESCRIPTION
from fleet.wire import protocol as p
from fleet.wire.digests import hot_digest

if TYPE_CHECKING:
    from fleet.expand.bundle import Bundle
    from fleet.expand.expansion import Expansion
    from fleet.world.description import Pose2D


@dataclass
class DiffRow:
    robot: str
    agent: str
    change: str  # start, stop, restart, hot-update, move, unchanged
    detail: str = ""
    parameters: list[ParameterChange] = field(default_factory=list)  # of a restart or hot-update


# What a deploy does with the values `fleet param set` gave a robot (the agent's apply decides:
# a robot started anew gets the spec's values).
OVERRIDES_FATE = {"unchanged": "kept", "hot-update": "kept", "restart": "dropped", "move": "dropped"}
SHOWN_CHANGES = 6  # parameter changes named in a row's detail; --json has them all


def diff(
    expansion: Expansion,
    view: FleetView,
    deployed: dict[str, p.BundleMessage] | None = None,
    discovery: DiscoveryPlan | None = None,
) -> list[DiffRow]:
    """What a deploy of `expansion` would change, robot by robot (live overrides shown as drift).
    `deployed`: robot -> its bundle in the desired state the router keeps; where that is the
    bundle its agent runs, a restart or hot-update names the parameters it changes.
    `discovery`: where the deploy would put the DDS discovery servers; robots whose server moves
    restart (their agent restarts every unit whose environment changes)."""
    current = {row.name: row for row in view.robots_of(expansion.fleet)}
    deployed = deployed or {}
    moving = _servers_moving(expansion, view, discovery) if discovery else {}
    rows = []
    for bundle in expansion.bundles:
        running = current.pop(bundle.name, None)
        hot = hot_digest(bundle.files, bundle.hot_files)
        if running is None:
            rows.append(DiffRow(bundle.name, bundle.agent, "start"))
        elif not running.digest:  # only the registry's plan knows it: its agent never ran it, or is away
            detail = f"agent {running.agent} offline: running state unknown" if running.state == "offline" else ""
            rows.append(DiffRow(bundle.name, bundle.agent, "start" if not detail else "unknown", detail))
        elif running.agent != bundle.agent:
            rows.append(DiffRow(bundle.name, bundle.agent, "move", f"from agent {running.agent}"))
        elif running.digest != bundle.digest:
            rows.append(_changed(bundle, running, deployed.get(bundle.name), "restart"))
        elif running.hot_digest != hot:
            rows.append(_changed(bundle, running, deployed.get(bundle.name), "hot-update"))
        elif running.state == "offline":
            rows.append(DiffRow(bundle.name, bundle.agent, "unchanged", "agent offline"))
        else:
            rows.append(DiffRow(bundle.name, bundle.agent, "unchanged"))
        row = rows[-1]
        fate = OVERRIDES_FATE.get(row.change)  # the agent keeps or drops them by the bundle's change
        if bundle.agent in moving and row.change in ("unchanged", "hot-update"):
            row.change, row.detail = "restart", _joined(moving[bundle.agent], row.detail)
        if running is not None and running.overrides and fate:
            from fleet.spec.rcl_types import value_text  # not at the top: fleet.spec reads YAML, status does not

            drift = "; ".join(
                f"{node} {name}={value_text(value)}"
                for node, values in sorted(running.overrides.items())
                for name, value in sorted(values.items())
            )
            row.detail = _joined(row.detail, f"live overrides {fate}: {drift}")
    for name, left in sorted(current.items()):
        rows.append(DiffRow(name, left.agent, "stop", "not in the spec any more"))
    return rows


def _joined(*parts: str) -> str:
    return "; ".join(part for part in parts if part)


def _servers_moving(expansion: Expansion, view: FleetView, discovery: DiscoveryPlan) -> dict[str, str]:
    """Agent -> why its robots restart: the DDS discovery server they use, as their agent reports
    it, is not the one the deploy gives them (pure)."""
    if discovery.local:  # the zenoh transport: each agent its own
        planned, whose = dict(discovery.local), "its"
    elif discovery.server:
        planned, whose = dict.fromkeys((bundle.agent for bundle in expansion.bundles), discovery.server), "the fleet's"
    else:  # its host's address is not known yet: the agents will find it (fleet.server.agent)
        return {}
    in_use = view.servers_in_use.get(expansion.fleet, {})
    return {
        agent: f"{whose} DDS discovery server moves: {in_use[agent]} -> {server}"
        if in_use[agent]
        else f"gets {whose} DDS discovery server {server}"
        for agent, server in planned.items()
        if in_use.get(agent, server) != server
    }


def _changed(bundle: Bundle, running: RobotRow, old: p.BundleMessage | None, change: str) -> DiffRow:
    """A restart or hot-update row, naming what changed when `old` is the bundle that runs."""
    generic = "launch description or parameters changed" if change == "restart" else ", ".join(sorted(bundle.hot_files))
    if old is None or (old.digest, old.hot_digest) != (running.digest, running.hot_digest):
        # the router's copy is not what runs (a deploy under way, or one the agent refused)
        return DiffRow(bundle.name, bundle.agent, change, generic)
    parameters = parameter_changes(dict(old.files), dict(bundle.files))
    named = [str(one) for one in parameters[:SHOWN_CHANGES]]
    if len(parameters) > SHOWN_CHANGES:
        named.append(f"and {len(parameters) - SHOWN_CHANGES} more (--json)")
    named += [
        _option_change(name, old.options, bundle.options)
        for name in sorted(old.options.keys() | bundle.options.keys())
        if old.options.get(name) != bundle.options.get(name)
    ]
    if old.entry != bundle.entry:
        named.append(f"launch file {old.entry} -> {bundle.entry}")
    described = {name for name in old.files.keys() | bundle.files.keys() if name.endswith(PARAMS_SUFFIX)}
    if bundle.kind == "world" and old.files.get(WORLD_DESCRIPTION) != bundle.files.get(WORLD_DESCRIPTION):
        world = _world_changes(old.files.get(WORLD_DESCRIPTION, ""), bundle.files.get(WORLD_DESCRIPTION, ""))
        if world is not None:
            named += world
            described.add(WORLD_DESCRIPTION)
    others = sorted(
        name
        for name in old.files.keys() | bundle.files.keys()
        if name not in described and old.files.get(name) != bundle.files.get(name)
    )
    if others:
        named.append(f"{', '.join(others)} changed")
    return DiffRow(bundle.name, bundle.agent, change, "; ".join(named) or generic, parameters)


def _option_change(name: str, old: Mapping[str, Any], new: Mapping[str, Any]) -> str:
    if name == SIMULATED_OPTION:  # only a real robot's options have it: "simulated None -> False" said nothing
        return "becomes simulated" if p.simulated_option(new) else "becomes real (simulated: false)"
    return f"{name} {old.get(name)!r} -> {new.get(name)!r}"


def _world_changes(old_text: str, new_text: str) -> list[str] | None:
    """What a new world description does to the running world, in its words (None: one of the
    two does not parse, and the row just names the file)."""
    # Imported here: the world's reader brings pydantic models and YAML, off `fleet status`'s path.
    from fleet.world.description import WorldError, parse_world

    try:
        old, new = parse_world(old_text), parse_world(new_text)
    except WorldError:
        return None
    changes = []
    before, after = {r.name: r for r in old.robots}, {r.name: r for r in new.robots}
    for name in sorted(before.keys() | after.keys()):
        if name not in before:
            changes.append(f"{name} joins at {_at(after[name].pose)}")
        elif name not in after:
            changes.append(f"{name} leaves")
        elif (change := before[name].reload_change(after[name])) == "respawn":
            changes.append(f"{name} respawns at {_at(after[name].pose)}")
        elif change == "rebuild":
            changes.append(f"{name} rebuilt where it stands")
    was, now = {o.name: o for o in old.obstacles}, {o.name: o for o in new.obstacles}
    for name in sorted(was.keys() | now.keys()):
        if was.get(name) != now.get(name):
            what = "added" if name not in was else "removed" if name not in now else "changed"
            changes.append(f"obstacle {name} {what}")
    for setting in ("physics_rate", "real_time", "clock_rate"):
        if getattr(old, setting) != getattr(new, setting):
            when = " (at the world's next restart)" if setting == "physics_rate" else ""
            changes.append(f"{setting} {getattr(old, setting)!r} -> {getattr(new, setting)!r}{when}")
    return changes


def _at(pose: Pose2D) -> str:
    return f"({pose.x:g}, {pose.y:g}, yaw {pose.yaw:g})"
