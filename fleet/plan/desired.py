"""What should run where: an Expansion -> one desired state (ApplyRequest) per agent (pure).

Also the registry's record of the plan, and where the fleet's DDS discovery server runs.
"""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

from fleet.plan.discovery import DiscoveryPlan, local_servers, plan_discovery
from fleet.plan.view import FleetView
from fleet.rules import MAX_DOMAIN_ID
from fleet.wire import protocol as p

if TYPE_CHECKING:
    from fleet.expand.expansion import Expansion


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
            shared=[p.TopicRoute(**topic.route_fields) for topic in expansion.shared_topics(agent)],
            has_world=expansion.spec.world is not None,
        )
        for agent, bundles in sorted(by_agent.items())
    ]
    if expansion.transport == "zenoh":  # each agent its own discovery server, bridges between them
        if discovery is not None:
            servers = discovery.local
        else:
            servers = local_servers(sorted({b.agent for b in expansion.bundles}), expansion.domain_id)
        for request in requests:
            request.transport = "zenoh"
            request.discovery_server = servers.get(request.agent)
            request.discovery_host = request.agent if request.discovery_server else None
            request.bridge = expansion.bridge.get(request.agent, p.BridgeRoutes())
    return requests


def held_generation(requests: list[p.ApplyRequest], statuses: list[p.StatusReply]) -> int | None:
    """The generation every agent of `requests` already holds with exactly this content, or None
    when sending them could change something (an agent holds other content or another
    generation, holds nothing, did not answer, or another agent also serves the fleet).  Then a
    deploy has nothing to send."""
    if not requests:
        return None
    fleet = requests[0].fleet
    held = {status.agent.name: status for status in statuses if status.fleet == fleet and status.content_digest}
    if set(held) != {request.agent for request in requests}:
        return None
    if any(held[request.agent].content_digest != request.content_digest() for request in requests):
        return None
    generations = {status.generation for status in held.values()}
    return generations.pop() if len(generations) == 1 else None


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


def domain_clash(expansion: Expansion, view: FleetView) -> str | None:
    """Why the fleet cannot have its ROS domain, or None: another fleet on this router runs in it
    (agents report each fleet's domain).  Two fleets in one domain meet: nodes of the same names
    on the same topics, and both fleets' discovery servers want the domain's one port."""
    others = sorted(
        f for f, domain in view.domain_ids.items() if domain == expansion.domain_id and f != expansion.fleet
    )
    if not others:
        return None
    used = set(view.domain_ids.values())
    # the next one up (0 is every stray ROS node's default: not offered)
    after = [*range(expansion.domain_id + 1, MAX_DOMAIN_ID + 1), *range(1, expansion.domain_id)]
    free = next((domain for domain in after if domain not in used), None)
    return (
        f"ros.domain_id {expansion.domain_id} is fleet {others[0]}'s on this router: each fleet needs a ROS "
        f"domain of its own, or their nodes meet (domains in use: {', '.join(map(str, sorted(used)))}"
        + (f"; {free} is free)" if free is not None else ")")
    )


def discovery_for(expansion: Expansion, view: FleetView) -> DiscoveryPlan:
    """Where the fleet's discovery server runs, from the agents online in `view` (pure).  With the
    zenoh transport: the world agent's own (the one a test probe on its computer joins)."""
    agents = sorted({bundle.agent for bundle in expansion.bundles})
    if expansion.transport == "zenoh":
        host = _world_agent(expansion) or (agents[0] if agents else None)
        hostnames = {agent.name: agent.hostname for agent in view.agents if agent.hostname}
        servers = local_servers(agents, expansion.domain_id, hostnames)
        return DiscoveryPlan(host, servers.get(host) if host else None, local=servers)
    addresses = {agent.name: agent.address for agent in view.agents if agent.online and agent.address}
    hostnames = {agent.name: agent.hostname for agent in view.agents if agent.hostname}
    return plan_discovery(_world_agent(expansion), agents, addresses, expansion.domain_id, hostnames)


def plan_record(expansion: Expansion, generation: int) -> p.PlanRecord:
    return p.PlanRecord(
        fleet=expansion.fleet,
        generation=generation,
        robots={bundle.name: bundle.agent for bundle in expansion.bundles},
        deployed_at=time.time(),
    )
