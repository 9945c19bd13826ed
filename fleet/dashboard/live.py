"""The fleet as the dashboard shows it, kept current from the Zenoh network.

Agents put their status, and the world's state where the world runs, every 0.25 s while someone
subscribes (fleet.control.agent); this subscribes.  Rarer events call for a full read, the status
query `fleet status` sends, which also brings the router's registry (offline agents, the
deployed plan, the generation history): an agent's liveliness token appearing or going (it joined
or left a fleet, started or died), a plan put (a deploy or `fleet down`), the start, and every
FULL_READ_PERIOD (for what has no event: an idle agent, a router restart).

The state document is the FleetView of fleet.control.view.build_view, the one rule `fleet status`
uses, as `fleet status --json` prints it, plus `maps` (fleet -> its world's state: obstacles,
robot models, trails, lidar hits, contacts) and `history` (fleet -> its last deploys, oldest
first, each generation as a string).  Zenoh callbacks only keep the payload and signal; decoding waits for snapshot().
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from fleet.control import protocol as p
from fleet.control.client import ControlClient
from fleet.control.view import FleetView, RobotRow, build_view
from fleet.errors import ControlError

log = logging.getLogger("fleet.dashboard")

FULL_READ_PERIOD = 10.0
REQUEST_TIMEOUT = 5.0


class LiveFleet:
    def __init__(self, client: ControlClient, fleet: str | None = None):
        self.client = client
        self.fleet = fleet
        self.on_change: Callable[[], None] = lambda: None  # called on Zenoh's threads: keep it tiny
        self._lock = threading.Lock()
        self._statuses: dict[str, bytes] = {}  # status key (fleet and agent) -> latest StatusReply
        self._worlds: dict[str, bytes] = {}  # world key (fleet and agent) -> latest WorldReply
        self._registries: list[p.RegistryReply] = []
        self._view: FleetView | None = None
        self._full_read = threading.Event()
        self._stop = threading.Event()
        self._subscribers: list[Any] = []
        self._reader = threading.Thread(target=self._read_loop, name="fleet-dashboard-read", daemon=True)

    def start(self) -> None:
        session = self.client.session
        fleet = self.fleet or "*"
        self._subscribers = [
            session.declare_subscriber(p.agent_status_key(fleet, "*"), self._on_status),
            session.declare_subscriber(p.world_key(fleet, "*"), self._on_world),
            session.liveliness().declare_subscriber(p.alive_key(fleet, "*"), self._on_membership),
            session.declare_subscriber(p.plan_key(fleet), self._on_membership),
        ]
        self._full_read.set()
        self._reader.start()

    def close(self) -> None:
        self._stop.set()
        self._full_read.set()
        for subscriber in self._subscribers:
            subscriber.undeclare()
        self._reader.join()

    # -- Zenoh callbacks ----------------------------------------------------------------------------

    def _on_status(self, sample) -> None:
        with self._lock:
            self._statuses[str(sample.key_expr)] = sample.payload.to_bytes()
        self.on_change()

    def _on_world(self, sample) -> None:
        with self._lock:
            self._worlds[str(sample.key_expr)] = sample.payload.to_bytes()
        self.on_change()

    def _on_membership(self, sample) -> None:
        import zenoh

        parts = str(sample.key_expr).split("/")  # fleet/<fleet>/alive/agent/<agent>, or fleet/<fleet>/plan
        if sample.kind == zenoh.SampleKind.DELETE and len(parts) == 5:
            with self._lock:  # gone now: its last status must not linger until the full read
                self._statuses.pop(p.agent_status_key(parts[1], parts[4]), None)
                self._worlds.pop(p.world_key(parts[1], parts[4]), None)
            self.on_change()
        self._full_read.set()

    def _read_loop(self) -> None:
        while True:
            self._full_read.wait(FULL_READ_PERIOD)
            if self._stop.is_set():
                return
            self._full_read.clear()
            try:
                statuses, registries = self.client.status(self.fleet)
            except Exception as error:  # no router now: subscriptions resume when it is back
                log.warning("status query failed: %s", error)
                continue
            with self._lock:
                self._statuses = {p.agent_status_key(s.fleet or "*", s.agent.name): p.encode(s) for s in statuses}
                self._registries = registries
            self.on_change()

    # -- the state document -------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            raw_statuses = list(self._statuses.values())
            raw_worlds = list(self._worlds.values())
            registries = list(self._registries)
        now = time.time()
        view = build_view(_decoded(raw_statuses, p.StatusReply), registries, now)
        self._view = view
        document = view.to_json()
        document["time"] = now
        document["maps"] = {reply.fleet: reply.world.model_dump() for reply in _decoded(raw_worlds, p.WorldReply)}
        document["history"] = {r.fleet: [_plan_json(plan) for plan in r.history] for r in registries}
        return document

    # -- requests on a robot (those of `fleet logs` and `fleet param get`) -----------------------

    def logs(self, fleet: str, robot: str, tail: int) -> list[dict[str, str]]:
        agent = self._agent_of(fleet, robot)
        request = p.LogsRequest(fleet=fleet, robot=robot, tail=tail)
        reply = self.client.request(p.logs_key(fleet, agent), request, p.LogsReply, f"agent {agent}", REQUEST_TIMEOUT)
        return [line.model_dump() for line in reply.lines]

    def parameter(self, fleet: str, robot: str, node: str, name: str) -> dict[str, Any]:
        """One parameter's live value, read from the node by its agent; ValueError for a bad name."""
        from fleet.control.agent import PARAM_TIMEOUT

        agent = self._agent_of(fleet, robot)
        request = p.ParamRequest(fleet=fleet, robot=robot, node=node, name=name, op="get")
        reply = self.client.request(
            p.param_key(fleet, agent), request, p.ParamReply, f"agent {agent}", PARAM_TIMEOUT + 5
        )  # the agent's own wait, plus the round trip
        return {"ok": reply.ok, "value": reply.value, "reason": reply.reason}

    def deployed_parameters(self, fleet: str, robot: str) -> list[dict[str, Any]]:
        """The robot's parameters as deployed (its params files in the desired state the router
        keeps), with the live overrides its agent reports."""
        import yaml

        row = self._row(fleet, robot)
        try:
            desired = self.client.request(
                p.desired_key(fleet, row.agent), p.DesiredQuery(), p.ApplyRequest, "the router", REQUEST_TIMEOUT
            )
        except ControlError:
            raise ControlError(f"the router keeps no deployed state of {robot} (see `fleet deploy`)") from None
        bundle = next((b for b in desired.bundles if b.name == robot), None)
        values: dict[str, dict[str, Any]] = {}
        for name, text in sorted(bundle.files.items()) if bundle else []:
            if name.endswith(".params.yaml"):
                for fqn, section in (yaml.safe_load(text) or {}).items():
                    values.setdefault(fqn, {}).update((section or {}).get("ros__parameters", {}))
        rows = []
        for fqn, parameters in values.items():
            overrides = row.overrides.get(fqn, {})
            for name, value in {**parameters, **overrides}.items():
                node = fqn.rsplit("/", 1)[-1]
                rows.append({"node": node, "fqn": fqn, "name": name, "value": value, "override": name in overrides})
        return rows

    def _row(self, fleet: str, robot: str) -> RobotRow:
        rows = self._view.find_robot(robot, fleet) if self._view else []
        if not rows or rows[0].state in ("pending", "offline"):
            raise ControlError(f"no running robot named {robot!r} in fleet {fleet}")
        return rows[0]

    def _agent_of(self, fleet: str, robot: str) -> str:
        return self._row(fleet, robot).agent


def _plan_json(plan: p.PlanRecord) -> dict[str, Any]:
    """A plan record with its generation as a string: a JavaScript number cannot hold 19 digits."""
    return {**plan.model_dump(), "generation": str(plan.generation)}


def _decoded(payloads: list[bytes], model: type[p.Message]) -> list[Any]:
    """The payloads that are valid messages (another version of fleet on the router is skipped)."""
    messages = []
    for payload in payloads:
        try:
            messages.append(p.decode(payload, model))
        except p.ProtocolError:
            continue
    return messages
