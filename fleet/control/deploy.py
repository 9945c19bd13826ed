"""Deploy, diff and down: turn an Expansion into per-agent desired states and follow them.

Planning is pure (requests_for, diff); the Deployment object does the talking and waiting and
reports through callbacks, so the CLI decides how it looks.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from fleet.control import protocol as p
from fleet.control.client import ControlClient
from fleet.control.view import FleetView, RobotRow, build_view
from fleet.dataplane.discovery import DiscoveryPlan, local_servers, plan_discovery
from fleet.errors import ControlError

if TYPE_CHECKING:
    from fleet.expand.expansion import Expansion

POLL_INTERVAL = 0.1


def new_generation() -> int:
    """Time-based: a later deploy (from any machine with a sane clock) has a larger number."""
    return time.time_ns()


def requests_for(
    expansion: Expansion, generation: int, serving: set[str], discovery: DiscoveryPlan | None = None
) -> list[p.ApplyRequest]:
    """A complete desired state for every agent with bundles, and an empty one for agents that
    run this fleet now but get nothing from this spec (so they stop its robots).  `discovery`
    says where the fleet's DDS discovery server runs (None: nowhere, nodes stay on their computer)."""
    by_agent: dict[str, list[p.BundleMessage]] = {}
    for bundle in expansion.bundles:
        by_agent.setdefault(bundle.agent, []).append(p.BundleMessage.from_bundle(bundle))
    for agent in serving:
        by_agent.setdefault(agent, [])
    now = time.time()
    requests = [
        p.ApplyRequest(
            fleet=expansion.fleet,
            agent=agent,
            generation=generation,
            domain_id=expansion.domain_id,
            bundles=bundles,
            sent_at=now,
            discovery_server=discovery.server if discovery else None,
            discovery_host=discovery.host if discovery else None,
        )
        for agent, bundles in sorted(by_agent.items())
    ]
    if expansion.transport == "zenoh":  # each agent its own discovery server, bridges between them
        servers = local_servers(sorted({b.agent for b in expansion.bundles}), expansion.domain_id)
        for request in requests:
            request.transport = "zenoh"
            request.discovery_server = servers.get(request.agent)
            request.discovery_host = request.agent if request.discovery_server else None
            request.bridge = expansion.bridge.get(request.agent, p.BridgeRoutes())
    return requests


def _world_agent(expansion: Expansion) -> str | None:
    return next((bundle.agent for bundle in expansion.bundles if bundle.kind == "world"), None)


def with_planned_agents(
    requests: list[p.ApplyRequest], registries: list[p.RegistryReply], fleet: str, generation: int, domain_id: int
) -> list[p.ApplyRequest]:
    """`requests` plus an empty desired state for every agent the last plan placed robots on
    that gets none now (an agent away right now stops them when it comes back)."""
    planned = {agent for r in registries if r.fleet == fleet and r.plan for agent in r.plan.robots.values()}
    missing = sorted(planned - {request.agent for request in requests})
    return requests + [
        p.ApplyRequest(
            fleet=fleet, agent=agent, generation=generation, domain_id=domain_id, bundles=[], sent_at=time.time()
        )
        for agent in missing
    ]


def discovery_for(expansion: Expansion, view: FleetView) -> DiscoveryPlan:
    """Where the fleet's discovery server runs, from the agents online in `view` (pure).  With the
    zenoh transport: the world agent's own (the one a test probe on its computer joins)."""
    agents = sorted({bundle.agent for bundle in expansion.bundles})
    if expansion.transport == "zenoh":
        host = _world_agent(expansion) or (agents[0] if agents else None)
        return DiscoveryPlan(host, local_servers(agents, expansion.domain_id).get(host) if host else None)
    addresses = {agent.name: agent.address for agent in view.agents if agent.online and agent.address}
    return plan_discovery(_world_agent(expansion), agents, addresses, expansion.domain_id)


def plan_record(expansion: Expansion, generation: int) -> p.PlanRecord:
    return p.PlanRecord(
        fleet=expansion.fleet,
        generation=generation,
        robots={bundle.name: bundle.agent for bundle in expansion.bundles},
        deployed_at=time.time(),
    )


@dataclass
class DiffRow:
    robot: str
    agent: str
    change: str  # start, stop, restart, hot-update, move, unchanged
    detail: str = ""


def diff(expansion: Expansion, view: FleetView) -> list[DiffRow]:
    """What a deploy of `expansion` would change, robot by robot (live overrides shown as drift)."""
    current = {row.name: row for row in view.robots_of(expansion.fleet)}
    rows = []
    for bundle in expansion.bundles:
        running = current.pop(bundle.name, None)
        hot = p.hot_digest(dict(bundle.files), list(bundle.hot_files))
        if running is None:
            rows.append(DiffRow(bundle.name, bundle.agent, "start"))
        elif not running.digest:  # only the registry's plan knows it: its agent never ran it, or is away
            detail = f"agent {running.agent} offline: running state unknown" if running.state == "offline" else ""
            rows.append(DiffRow(bundle.name, bundle.agent, "start" if not detail else "unknown", detail))
        elif running.agent != bundle.agent:
            rows.append(DiffRow(bundle.name, bundle.agent, "move", f"from agent {running.agent}"))
        elif running.digest != bundle.digest:
            rows.append(DiffRow(bundle.name, bundle.agent, "restart", "launch description or parameters changed"))
        elif running.hot_digest != hot:
            rows.append(DiffRow(bundle.name, bundle.agent, "hot-update", ", ".join(sorted(bundle.hot_files))))
        elif running.state == "offline":
            rows.append(DiffRow(bundle.name, bundle.agent, "unchanged", "agent offline"))
        else:
            rows.append(DiffRow(bundle.name, bundle.agent, "unchanged"))
        if running is not None and running.overrides and rows[-1].change in ("unchanged", "hot-update"):
            drift = "; ".join(
                f"{node} {name}={value!r}"
                for node, values in sorted(running.overrides.items())
                for name, value in sorted(values.items())
            )
            rows[-1].detail = (rows[-1].detail + "; " if rows[-1].detail else "") + f"live overrides kept: {drift}"
    for name, row in sorted(current.items()):
        rows.append(DiffRow(name, row.agent, "stop", "not in the spec any more"))
    return rows


@dataclass
class Outcome:
    generation: int
    replies: dict[str, p.ApplyReply | ControlError] = field(default_factory=dict)
    view: FleetView | None = None
    superseded_by: int | None = None
    timed_out: bool = False
    discovery: DiscoveryPlan | None = None

    @property
    def unreachable(self) -> dict[str, str]:
        return {agent: str(r) for agent, r in self.replies.items() if isinstance(r, ControlError)}

    @property
    def refused(self) -> dict[str, str]:
        return {agent: r.reason for agent, r in self.replies.items() if isinstance(r, p.ApplyReply) and not r.accepted}

    @property
    def nothing_changed(self) -> bool:
        accepted = [r for r in self.replies.values() if isinstance(r, p.ApplyReply) and r.accepted]
        return bool(accepted) and len(accepted) == len(self.replies) and all(r.changes.nothing for r in accepted)

    @property
    def ok(self) -> bool:
        return (
            not self.unreachable
            and not self.refused
            and self.superseded_by is None
            and not self.timed_out
            and self.view is not None
            and self.view.all_running
        )


def deploy(
    client: ControlClient,
    expansion: Expansion,
    wait: bool = True,
    timeout: float = 60.0,
    on_progress: Callable[[list[RobotRow]], None] | None = None,
) -> Outcome:
    statuses, registries = client.status(expansion.fleet)
    before = build_view(statuses, registries, time.time())
    outcome = Outcome(generation=new_generation(), discovery=discovery_for(expansion, before))
    requests = requests_for(expansion, outcome.generation, before.agents_serving(expansion.fleet), outcome.discovery)
    outcome.replies = client.send_applies(requests)
    # After the applies (an agent that took its apply directly then holds this generation already):
    # the router keeps each desired state for agents that were away, and the plan for status.
    client.put_desired(
        with_planned_agents(requests, registries, expansion.fleet, outcome.generation, expansion.domain_id)
    )
    client.put_plan(plan_record(expansion, outcome.generation))
    for reply in outcome.replies.values():
        if isinstance(reply, p.ApplyReply) and not reply.accepted and reply.current_generation > outcome.generation:
            outcome.superseded_by = max(outcome.superseded_by or 0, reply.current_generation)
    wanted = {b.name for b in expansion.bundles if not isinstance(outcome.replies.get(b.agent), ControlError)}
    deadline = time.monotonic() + timeout
    while True:
        statuses, registries = client.status(expansion.fleet)
        view = build_view(statuses, registries, time.time())
        outcome.view = view.only(expansion.fleet)
        for (_fleet, _agent), generation in view.generations.items():
            if generation > outcome.generation:
                outcome.superseded_by = max(outcome.superseded_by or 0, generation)
        if on_progress is not None:
            on_progress(outcome.view.robots)
        if not wait or outcome.superseded_by is not None:
            break
        if _settled(outcome.view, wanted, outcome.generation) or _hopeless(outcome.view, wanted, outcome.generation):
            break
        if time.monotonic() >= deadline:
            outcome.timed_out = True
            break
        time.sleep(POLL_INTERVAL)
    return outcome


def _settled(view: FleetView, wanted: set[str], generation: int) -> bool:
    """Every robot we could send runs at (at least) our generation, and removed ones are gone."""
    rows = {row.name: row for row in view.robots}
    for name in wanted:
        row = rows.get(name)
        if row is None or row.state != "running" or row.generation < generation:
            return False
    # Rows only the registry knows (pending, offline) are not running anywhere: they don't count.
    return all(row.name in wanted or row.state in ("pending", "offline") for row in view.robots)


def _hopeless(view: FleetView, wanted: set[str], generation: int) -> bool:
    """Every robot is running or failed for good (its launch file could not start): stop waiting."""
    rows = {row.name: row for row in view.robots}
    failed = [n for n in wanted if n in rows and rows[n].error and rows[n].generation >= generation]
    others = [n for n in wanted if n not in failed]
    return bool(failed) and all(
        n in rows and rows[n].state == "running" and rows[n].generation >= generation for n in others
    )


def down(
    client: ControlClient, fleet: str, wait: bool = True, timeout: float = 30.0
) -> dict[str, p.ApplyReply | ControlError]:
    """Send every agent serving `fleet` an empty desired state (left with the router too, for
    agents away now) and forget the plan."""
    statuses, registries = client.status(fleet)
    view = build_view(statuses, registries, time.time())
    generation = new_generation()
    serving = sorted(view.agents_serving(fleet))
    requests = [
        p.ApplyRequest(
            fleet=fleet,
            agent=agent,
            generation=generation,
            domain_id=view.domain_ids.get(fleet, 0),
            bundles=[],
            sent_at=time.time(),
        )
        for agent in serving
    ]
    replies = client.send_applies(requests) if requests else {}
    client.put_desired(with_planned_agents(requests, registries, fleet, generation, view.domain_ids.get(fleet, 0)))
    client.put_plan(p.PlanRecord(fleet=fleet, generation=generation, robots={}, deployed_at=time.time()))
    deadline = time.monotonic() + timeout
    while wait and requests and time.monotonic() < deadline:
        statuses, _ = client.status(fleet)
        if not any(status.robots for status in statuses if status.fleet == fleet):
            break
        time.sleep(POLL_INTERVAL)
    return replies
