"""The router: a Zenoh session in router mode, plus the registry that remembers what the CLI can't.

The CLI is short-lived, so someone must remember which agents were seen when, and what was
deployed where (to show the robots of an offline agent).  The router is always there, so it
keeps that registry: it watches the agents' liveliness tokens, stores the plan record each
deploy puts on `fleet/<fleet>/plan` (the last HISTORY of them: the fleet's generation history),
and answers `fleet/<fleet>/status/registry` as part of the one wildcard status query.  It also
stores each agent's latest desired state (the apply a deploy or `fleet down` puts on
`fleet/<fleet>/desired/<agent>`) and hands it to the agent when asked, so an agent that was away
when the deploy ran completes it when it comes back.  With --state-dir the registry survives
router restarts.
"""

from __future__ import annotations

import json
import logging
import threading
import time
from pathlib import Path

from fleet.files import write_atomic
from fleet.rules import registry_file
from fleet.wire import protocol as p

log = logging.getLogger("fleet.router")

HISTORY = 20  # plan records kept per fleet, newest last


class Registry:
    def __init__(self, state_file: Path | None = None):
        self.state_file = state_file
        self._lock = threading.Lock()
        self._plans: dict[str, p.PlanRecord] = {}
        self._history: dict[str, list[p.PlanRecord]] = {}  # fleet -> its last HISTORY plans, oldest first
        self._agents: dict[str, dict[str, p.AgentSeen]] = {}  # fleet -> agent -> seen
        self._desired: dict[str, dict[str, p.ApplyRequest]] = {}  # fleet -> agent -> latest apply
        self._load()

    def _load(self) -> None:
        if self.state_file is None or not self.state_file.exists():
            return
        try:
            data = json.loads(self.state_file.read_text())
            self._plans = {f: p.PlanRecord.model_validate(v) for f, v in data.get("plans", {}).items()}
            self._history = {
                f: [p.PlanRecord.model_validate(plan) for plan in plans] for f, plans in data.get("history", {}).items()
            }
            self._desired = {
                f: {a: p.ApplyRequest.model_validate(r) for a, r in agents.items()}
                for f, agents in data.get("desired", {}).items()
            }
            for fleet, agents in data.get("agents", {}).items():
                # After a router restart nobody is known to be online until its token shows up.
                self._agents[fleet] = {
                    a: p.AgentSeen(online=False, last_seen=s["last_seen"]) for a, s in agents.items()
                }
        except Exception as error:
            log.error("ignoring unreadable registry %s: %s", self.state_file, error)

    def _save(self) -> None:
        if self.state_file is None:
            return
        data = {
            "plans": {f: plan.model_dump() for f, plan in self._plans.items()},
            "history": {f: [plan.model_dump() for plan in plans] for f, plans in self._history.items()},
            "agents": {f: {a: s.model_dump() for a, s in agents.items()} for f, agents in self._agents.items()},
            "desired": {f: {a: r.model_dump() for a, r in agents.items()} for f, agents in self._desired.items()},
        }
        write_atomic(self.state_file, json.dumps(data), durable=True)

    # Zenoh callbacks: tiny dictionary updates (and a small file write on a deploy).

    def on_liveliness(self, sample) -> None:
        import zenoh

        parts = str(sample.key_expr).split("/")  # fleet/<fleet>/alive/agent/<agent>
        if len(parts) != 5:
            return
        fleet, agent = parts[1], parts[4]
        online = sample.kind == zenoh.SampleKind.PUT
        with self._lock:
            self._agents.setdefault(fleet, {})[agent] = p.AgentSeen(online=online, last_seen=time.time())

    def on_plan(self, sample) -> None:
        try:
            plan = p.decode(sample.payload.to_bytes(), p.PlanRecord)
        except p.ProtocolError as error:
            log.warning("ignoring plan on %s: %s", sample.key_expr, error)
            return
        with self._lock:
            held = self._plans.get(plan.fleet)
            if held is None or plan.generation >= held.generation:
                self._plans[plan.fleet] = plan
                history = [kept for kept in self._history.get(plan.fleet, []) if kept.generation != plan.generation]
                self._history[plan.fleet] = [*history, plan][-HISTORY:]  # `fleet down` included
                if not plan.robots:  # `fleet down`: forget the fleet
                    self._plans.pop(plan.fleet)
                    self._agents.pop(plan.fleet, None)
                self._save()

    def on_desired(self, sample) -> None:
        try:
            request = p.decode(sample.payload.to_bytes(), p.ApplyRequest)
        except p.ProtocolError as error:
            log.warning("ignoring desired state on %s: %s", sample.key_expr, error)
            return
        if str(sample.key_expr) != p.desired_key(request.fleet, request.agent):
            log.warning("ignoring desired state for %s/%s put on %s", request.fleet, request.agent, sample.key_expr)
            return
        with self._lock:
            held = self._desired.get(request.fleet, {}).get(request.agent)
            if held is None or request.generation >= held.generation:  # the later generation wins
                self._desired.setdefault(request.fleet, {})[request.agent] = request
                self._save()

    def on_desired_query(self, query) -> None:
        """Reply with each stored desired state newer than what the asking agent holds."""
        import zenoh

        try:
            payload = query.payload
            asked = p.decode(payload.to_bytes(), p.DesiredQuery) if payload is not None else p.DesiredQuery()
        except p.ProtocolError as error:
            query.reply_err(p.error_reply(error))
            return
        wanted = zenoh.KeyExpr(str(query.key_expr))
        with self._lock:
            replies = [
                (p.desired_key(fleet, agent), p.encode(request))
                for fleet, agents in self._desired.items()
                for agent, request in agents.items()
                if wanted.intersects(zenoh.KeyExpr(p.desired_key(fleet, agent)))
                and request.generation > asked.held.get(fleet, -1)
                and (request.bundles or fleet in asked.held)  # a `fleet down` only for a fleet it holds
            ]
        for key, payload in replies:
            query.reply(key, payload)
        if p.fleet_of_key(query.key_expr) is None:  # an agent's periodic ask (any fleet): say it was heard
            query.reply(str(query.key_expr), p.encode(p.DesiredDone(sent=len(replies))))

    def on_query(self, query) -> None:
        wanted = p.fleet_of_key(query.key_expr)
        with self._lock:
            fleets = [wanted] if wanted else sorted(set(self._plans) | set(self._agents))
            replies = []
            now = time.time()
            for fleet in fleets:
                agents = {
                    a: p.AgentSeen(online=s.online, last_seen=now if s.online else s.last_seen)
                    for a, s in self._agents.get(fleet, {}).items()
                }
                registry = p.RegistryReply(
                    fleet=fleet,
                    plan=self._plans.get(fleet),
                    agents=agents,
                    history=list(self._history.get(fleet, [])),
                )
                replies.append((fleet, registry))
        for fleet, reply in replies:
            query.reply(p.registry_key(fleet), p.encode(reply))


def serve_router(session, registry: Registry):
    """Declare the registry's entities on an open router session; returns them (keep them alive)."""

    def echo(sample) -> None:  # the bridges' probe of their path through the router
        _, fleet, _, agent, *_ = str(sample.key_expr).split("/")  # fleet/<fleet>/agent/<agent>/echo/ping
        session.put(p.echo_keys(fleet, agent)[1], sample.payload)

    return [
        session.declare_subscriber(p.echo_keys("*", "*")[0], echo),
        session.liveliness().declare_subscriber("fleet/*/alive/agent/*", registry.on_liveliness, history=True),
        session.declare_subscriber("fleet/*/plan", registry.on_plan),
        session.declare_queryable("fleet/*/status/registry", registry.on_query),
        session.declare_subscriber(p.desired_key("*", "*"), registry.on_desired),
        session.declare_queryable(p.desired_key("*", "*"), registry.on_desired_query),
    ]


def run_router(listen: list[str], zenoh_config: Path | None, state_dir: Path | None, stop: threading.Event) -> None:
    from fleet.wire.session import open_router, router_config, router_listens

    registry = Registry(registry_file(state_dir) if state_dir else None)
    config = router_config(listen, zenoh_config)  # read once: its files and certificates are checked
    with open_router(config) as session:
        entities = serve_router(session, registry)
        log.info("router listening on %s", ", ".join(router_listens(config)))
        while not stop.wait(0.5):  # a timed wait lets signal handlers run
            pass
        for entity in entities:
            entity.undeclare()
