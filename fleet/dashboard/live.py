"""The fleet as the dashboard shows it, kept current from the Zenoh network.

The dashboard sends the status query `fleet status` sends (one wildcard get: every agent's
status and the router's registry: offline agents, the deployed plan, the generation history)
every READ_PERIOD, and asks each fleet's world agent for the world's state (obstacles, robot
models, trails, lidar hits, contacts) as often; an agent's liveliness token appearing or going,
or a plan put (a deploy or `fleet down`), calls for a read at once.  Why queries and not agents
putting their status while someone subscribes: an agent's session that declared publishers on
the keys of its own queryables stalled under a router's link changes (the multi-computer test
failed in 2 of 3 runs with them, passed 3 of 3 without).

The state document is the FleetView of fleet.plan.view.build_view, the one rule `fleet status`
uses, as `fleet status --json` prints it, plus `maps` (fleet -> its world's state) and `history`
(fleet -> its last deploys, oldest first, each generation as a string).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from typing import Any

from fleet.client import ControlClient
from fleet.errors import ControlError
from fleet.plan import FleetView, RobotRow, build_view
from fleet.plan.parameters import bundle_parameters
from fleet.spec.rcl_types import value_text
from fleet.wire import protocol as p

log = logging.getLogger("fleet.dashboard")

READ_PERIOD = 0.5  # s between reads: the page is never more than this (plus a round trip) behind
REQUEST_TIMEOUT = 5.0


class UnknownRobot(ControlError):
    """The fleet has no robot of that name (the dashboard answers 404, where a robot that is there
    and cannot answer is the fleet's failure, 502)."""


class LiveFleet:
    def __init__(self, client: ControlClient, fleet: str | None = None):
        self.client = client
        self.fleet = fleet
        self.on_change: Callable[[], None] = lambda: None  # called on the reader's thread: keep it tiny
        self._lock = threading.Lock()
        self._statuses: list[p.StatusReply] = []
        self._worlds: list[p.WorldReply] = []
        self._registries: list[p.RegistryReply] = []
        self._view: FleetView | None = None
        self._read_now = threading.Event()
        self._stop = threading.Event()
        self._subscribers: list[Any] = []
        self._reader = threading.Thread(target=self._read_loop, name="fleet-dashboard-read", daemon=True)

    def start(self) -> None:
        session = self.client.session
        fleet = self.fleet or "*"
        self._subscribers = [
            session.liveliness().declare_subscriber(p.alive_key(fleet, "*"), self._on_event),
            session.declare_subscriber(p.plan_key(fleet), self._on_event),
        ]
        self._reader.start()

    def close(self) -> None:
        self._stop.set()
        self._read_now.set()
        for subscriber in self._subscribers:
            subscriber.undeclare()
        self._reader.join()

    def _on_event(self, sample) -> None:  # Zenoh thread: only signal
        self._read_now.set()

    def _read_loop(self) -> None:
        while not self._stop.is_set():
            self._read_now.clear()
            try:
                statuses, registries = self.client.status(self.fleet)
                worlds = []
                for status in statuses:
                    if status.world is not None and status.fleet:
                        try:
                            worlds.append(self.client.world(status.fleet, status.agent.name))
                        except ControlError as error:  # the world has not reported yet, or just left
                            log.debug("no world state from %s: %s", status.agent.name, error)
            except Exception as error:  # no router now: the next read tries again
                log.warning("status query failed: %s", error)
            else:
                with self._lock:
                    self._statuses, self._registries, self._worlds = statuses, registries, worlds
                self.on_change()
            self._read_now.wait(READ_PERIOD)

    # -- the state document -------------------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            statuses, worlds, registries = list(self._statuses), list(self._worlds), list(self._registries)
        now = time.time()
        view = build_view(statuses, registries, now)
        self._view = view
        document = view.to_json()
        document["time"] = now
        document["maps"] = {reply.fleet: reply.world.model_dump() for reply in worlds}
        document["history"] = {r.fleet: [_plan_json(plan) for plan in r.history] for r in registries}
        return document

    # -- requests on a robot (those of `fleet logs` and `fleet param get`) -----------------------

    def logs(self, fleet: str, robot: str, tail: int) -> list[dict[str, str]]:
        agent = self._agent_of(fleet, robot)
        reply = self.client.logs(agent, p.LogsRequest(fleet=fleet, robot=robot, tail=tail), REQUEST_TIMEOUT)
        return [line.model_dump() for line in reply.lines]

    def parameter(self, fleet: str, robot: str, node: str, name: str) -> dict[str, Any]:
        """One parameter's live value, read from the node by its agent; ValueError for a bad name."""
        agent = self._agent_of(fleet, robot)
        reply = self.client.param(agent, p.ParamRequest(fleet=fleet, robot=robot, node=node, name=name, op="get"))
        text = value_text(reply.value) if reply.ok else ""
        return {"ok": reply.ok, "value": reply.value, "text": text, "reason": reply.reason}

    def deployed_parameters(self, fleet: str, robot: str) -> list[dict[str, Any]]:
        """The robot's parameters as deployed (its params files in the desired state the router
        keeps), with the live overrides its agent reports."""
        row = self._row(fleet, robot)
        try:
            desired = self.client.request(
                p.desired_key(fleet, row.agent), p.DesiredQuery(), p.ApplyRequest, "the router", REQUEST_TIMEOUT
            )
        except ControlError:
            raise ControlError(f"the router keeps no deployed state of {robot} (see `fleet deploy`)") from None
        bundle = next((b for b in desired.bundles if b.name == robot), None)
        values = bundle_parameters(dict(bundle.files)) if bundle else {}
        rows = []
        for fqn, parameters in values.items():
            overrides = row.overrides.get(fqn, {})
            for name, value in {**parameters, **overrides}.items():
                node = fqn.rsplit("/", 1)[-1]
                # `text` as fleet shows values everywhere: JavaScript would write the double 1.0 as 1
                rows.append(
                    {
                        "node": node,
                        "fqn": fqn,
                        "name": name,
                        "value": value,
                        "text": value_text(value),
                        "override": name in overrides,
                    }
                )
        return rows

    def _row(self, fleet: str, robot: str) -> RobotRow:
        rows = self._view.find_robot(robot, fleet) if self._view else []
        if not rows:
            raise UnknownRobot(f"no robot named {robot!r} in fleet {fleet}")
        if rows[0].state in ("pending", "offline"):
            raise ControlError(f"robot {robot!r} of fleet {fleet} is not running ({rows[0].state})")
        return rows[0]

    def _agent_of(self, fleet: str, robot: str) -> str:
        return self._row(fleet, robot).agent


def _plan_json(plan: p.PlanRecord) -> dict[str, Any]:
    """A plan record with its generation as a string: a JavaScript number cannot hold 19 digits."""
    return {**plan.model_dump(), "generation": str(plan.generation)}
