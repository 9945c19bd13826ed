"""Deploy, down and restart: send each agent its desired state (planned by fleet.plan), or ask
it to start robots again, and follow them.

The talking and waiting are here; they report through callbacks, so the CLI decides how it looks.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from fleet.client.control_client import ControlClient
from fleet.client.robots import fleet_status, robot_place
from fleet.errors import ControlError, FleetError, Location, RouterSilent
from fleet.plan import (
    FleetView,
    RobotRow,
    build_view,
    discovery_for,
    domain_clash,
    held_generation,
    new_generation,
    plan_record,
    requests_for,
    with_planned_agents,
)
from fleet.plan.discovery import DiscoveryPlan
from fleet.rules import STABLE_AFTER
from fleet.wire import protocol as p

if TYPE_CHECKING:
    from fleet.expand.expansion import Expansion

POLL_INTERVAL = 0.1
# How long the router may take to hold a deploy's plan before the deploy leaves it again: a router
# that was still starting (its session open, its subscribers not yet declared) drops the puts.
RECORD_AGAIN = 1.0


@dataclass
class Outcome:
    generation: int
    replies: dict[str, p.ApplyReply | ControlError] = field(default_factory=dict)
    view: FleetView | None = None
    superseded_by: int | None = None
    timed_out: bool = False
    recorded: bool = False  # the router holds this deploy's plan (checked before judging robots)
    discovery: DiscoveryPlan | None = None
    # Every agent already held exactly this desired state: nothing was sent (`replies` is empty
    # and `generation` is the one they hold).
    already_applied: bool = False
    # agent -> robot -> why its unit could not start there: nothing was sent to any agent.
    problems: dict[str, dict[str, str]] = field(default_factory=dict)
    waited: bool = True  # for the robots to run (deploy --wait); else only until the router held it

    @property
    def unreachable(self) -> dict[str, str]:
        return {agent: str(r) for agent, r in self.replies.items() if isinstance(r, ControlError)}

    @property
    def refused(self) -> dict[str, str]:
        return {agent: r.reason for agent, r in self.replies.items() if isinstance(r, p.ApplyReply) and not r.accepted}

    @property
    def not_running(self) -> list[RobotRow]:
        """The fleet's robots not running when the deploy last looked: why a deploy is not up."""
        return [row for row in (self.view.robots if self.view else []) if row.state != "running"]

    @property
    def nothing_changed(self) -> bool:
        if self.already_applied:
            return True
        accepted = [r for r in self.replies.values() if isinstance(r, p.ApplyReply) and r.accepted]
        return bool(accepted) and len(accepted) == len(self.replies) and all(r.changes.nothing for r in accepted)

    def to_json(self) -> dict[str, Any]:
        """What `fleet deploy --json` prints."""
        replies = {}
        for agent_name, reply in self.replies.items():
            if isinstance(reply, p.ApplyReply):
                replies[agent_name] = reply.model_dump()
            else:
                replies[agent_name] = {"error": str(reply)}
        return {
            "ok": self.ok,
            "generation": self.generation,
            "nothing_changed": self.nothing_changed,
            "sent": not self.already_applied and not self.problems,
            "superseded_by": self.superseded_by,
            "timed_out": self.timed_out,
            "recorded": self.recorded,
            "problems": self.problems,
            "discovery": None
            if self.discovery is None
            else {"host": self.discovery.host, "server": self.discovery.server, "note": self.discovery.note},
            "agents": replies,
            "not_running": [
                {"name": row.name, "agent": row.agent, "state": row.state, "reason": row.reason}
                for row in self.not_running
            ],
            "status": self.view.to_json() if self.view else None,
        }

    @property
    def ok(self) -> bool:
        """The deploy was taken (every agent and the router hold it) and, when it waited, every
        robot runs.  `fleet deploy` exits 1 unless it is."""
        taken = (
            not self.problems
            and not self.unreachable
            and not self.refused
            and self.superseded_by is None
            and not self.timed_out
            and self.recorded
        )
        if not self.waited:
            return taken
        return taken and self.view is not None and self.view.all_running


def deploy(
    client: ControlClient,
    expansion: Expansion,
    wait: bool = True,
    timeout: float = 60.0,
    on_progress: Callable[[list[RobotRow]], None] | None = None,
) -> Outcome:
    statuses, registries = visible_statuses(client, expansion.fleet)
    before = build_view(statuses, registries, time.time())
    check_domain(expansion, before)
    outcome = Outcome(generation=new_generation(), discovery=discovery_for(expansion, before), waited=wait)
    requests = requests_for(expansion, outcome.generation, before.agents_serving(expansion.fleet), outcome.discovery)
    # What the router keeps: each desired state, for agents that are away, and the plan, for status.
    desired = with_planned_agents(requests, registries, expansion.fleet, outcome.generation, expansion.domain_id)
    plan = plan_record(expansion, outcome.generation)
    held = held_generation(requests, statuses)
    # A no-op redeploy whose router has no record of it (started again without its state
    # directory): the router is given the plan and the desired states again, at the generation
    # the agents hold, so that status shows the robots of an agent that goes away.
    restore = held is not None and not _plan_taken(registries, expansion.fleet, held)
    if held is not None:  # a no-op redeploy: the agents hold what is wanted
        outcome.generation, outcome.already_applied = held, True
        if restore:
            requests = [request.model_copy(update={"generation": held}) for request in requests]
            desired = with_planned_agents(requests, registries, expansion.fleet, held, expansion.domain_id)
            plan = plan_record(expansion, held)
            _record(client, desired, plan)
    else:
        outcome.problems = _problems(client, requests)
        if outcome.problems:
            return outcome  # nothing sent: the fleet runs as it was
        _send(client, requests, desired, plan, outcome)
    wanted = {b.name for b in expansion.bundles if not isinstance(outcome.replies.get(b.agent), ControlError)}
    deadline = time.monotonic() + timeout
    record_again = time.monotonic() + RECORD_AGAIN
    while True:
        if not outcome.already_applied or outcome.view is not None:  # else the status above is fresh
            statuses, registries = client.status(expansion.fleet)
        view = build_view(statuses, registries, time.time())
        outcome.view = view.only(expansion.fleet)
        for generation in outcome.view.generations.values():
            if generation > outcome.generation:
                outcome.superseded_by = max(outcome.superseded_by or 0, generation)
        if on_progress is not None:
            on_progress(outcome.view.robots)
        if outcome.superseded_by is not None:
            break
        # Even without waiting for the robots, the router must hold the plan and the desired
        # states before the session closes: closing right after the puts can lose them.
        judged = (outcome.already_applied and not restore) or _plan_taken(
            registries, expansion.fleet, outcome.generation
        )
        outcome.recorded = outcome.recorded or judged
        if judged and not wait:
            break
        if not judged and time.monotonic() >= record_again:
            _record(client, desired, plan)
            record_again = time.monotonic() + RECORD_AGAIN
        if judged and (
            _settled(outcome.view, wanted, outcome.generation) or _hopeless(outcome.view, wanted, outcome.generation)
        ):
            break
        if time.monotonic() >= deadline:
            outcome.timed_out = True
            break
        time.sleep(POLL_INTERVAL)
    return outcome


def visible_statuses(client: ControlClient, fleet: str) -> tuple[list[p.StatusReply], list[p.RegistryReply]]:
    """Every fleet's status, for check_domain: a ROS domain is one fleet's alone.  An operator
    whose access rules reach only this fleet's keys (docs/control-plane.md) gets this fleet's:
    the router denies the wildcard at once, and the others' domains cannot be checked."""
    try:
        return client.status(None)
    except RouterSilent:  # not a denial: asking for the fleet alone would wait as long again
        raise
    except ControlError:
        return client.status(fleet)


def check_domain(expansion: Expansion, view: FleetView) -> None:
    """Bad input (nothing is sent) when another fleet in `view`, every fleet on the router, runs
    in the fleet's ROS domain."""
    if clash := domain_clash(expansion, view):
        raise FleetError(clash, Location(expansion.spec.where("ros", "domain_id")))


def _problems(client: ControlClient, requests: list[p.ApplyRequest]) -> dict[str, dict[str, str]]:
    """Ask every agent whether it could start the robots it would start or change: agent -> robot
    -> problem.  An agent that does not answer is not asked again here: sending to it says so."""
    checks = client.send_applies([request.model_copy(update={"check_only": True}) for request in requests])
    return {
        agent: reply.problems
        for agent, reply in checks.items()
        if isinstance(reply, p.ApplyReply) and not reply.accepted and reply.problems
    }


def _send(
    client: ControlClient,
    requests: list[p.ApplyRequest],
    desired: list[p.ApplyRequest],
    plan: p.PlanRecord,
    outcome: Outcome,
) -> None:
    outcome.replies = client.send_applies(requests)
    # After the applies: an agent that took its apply directly then holds this generation already.
    _record(client, desired, plan)
    for reply in outcome.replies.values():
        if isinstance(reply, p.ApplyReply) and not reply.accepted and reply.current_generation > outcome.generation:
            outcome.superseded_by = max(outcome.superseded_by or 0, reply.current_generation)


def _record(client: ControlClient, desired: list[p.ApplyRequest], plan: p.PlanRecord) -> None:
    """Leave the deploy with the router.  Leaving it twice is harmless: the router keeps the
    later generation, and the same one again replaces it with itself."""
    client.put_desired(desired)
    client.put_plan(plan)


def _plan_taken(registries: list[p.RegistryReply], fleet: str, generation: int) -> bool:
    """The router's registry has taken this deploy's plan (or a later one).  It takes the plan (a
    put) and answers status (a query) on different threads, so the first status after a deploy
    can still carry the last plan, whose robots removed since would show as pending."""
    return any(r.fleet == fleet and any(plan.generation >= generation for plan in r.history) for r in registries)


def _settled(view: FleetView, wanted: set[str], generation: int) -> bool:
    """Every robot we could send runs steadily at (at least) our generation, and removed ones are gone."""
    rows = {row.name: row for row in view.robots}
    for name in wanted:
        row = rows.get(name)
        if row is None or row.state != "running" or row.generation < generation or not _steady(row):
            return False
    # Rows only the registry knows (pending, offline) are not running anywhere: they don't count.
    return all(row.name in wanted or row.state in ("pending", "offline") for row in view.robots)


CRASH_LOOP = 2  # restarts of a node, now waiting to be restarted again, after which waiting is no use


def _steady(row: RobotRow) -> bool:
    """No node of it was restarted less than STABLE_AFTER ago (the runner's own `healthy again`):
    a node that keeps exiting runs for a moment between its exits, and in a fleet without a world
    it may join the ROS graph in that moment, which alone would pass for `fleet up`."""
    return all(not node.get("restarts") or (node.get("uptime") or 0.0) >= STABLE_AFTER for node in row.nodes)


def _hopeless(view: FleetView, wanted: set[str], generation: int) -> bool:
    """Every robot is running, or will not run by waiting longer: it failed (its launch file could
    not start, a node ended and is not restarted) or a node of it keeps exiting.  Stop waiting."""
    rows = {row.name: row for row in view.robots}
    stuck = [n for n in wanted if n in rows and rows[n].generation >= generation and _stuck(rows[n])]
    others = [n for n in wanted if n not in stuck]
    return bool(stuck) and all(
        n in rows and rows[n].state == "running" and rows[n].generation >= generation for n in others
    )


def _stuck(row: RobotRow) -> bool:
    return row.state == "failed" or any(
        node.get("state") == "backoff" and node.get("restarts", 0) >= CRASH_LOOP for node in row.nodes
    )


@dataclass
class Restart:
    """`fleet restart`: each robot asked for, by (fleet, name), with its agent and the number of
    its restart there; the robots of their fleets that ran before the restart (a restarted world
    takes its robots' data away for a moment), and every robot of those fleets as last seen.
    Agents by when their process started: the one that answered, and as last seen."""

    asked: dict[tuple[str, str], tuple[str, int]]
    waited: bool = True
    ran_before: set[tuple[str, str]] = field(default_factory=set)
    seen: dict[tuple[str, str], RobotRow] = field(default_factory=dict)
    timed_out: bool = False
    agents_asked: dict[str, float] = field(default_factory=dict)
    agents_seen: dict[str, float] = field(default_factory=dict)

    @property
    def rows(self) -> dict[tuple[str, str], RobotRow]:
        """The robots asked for, as last seen."""
        return {key: row for key, row in self.seen.items() if key in self.asked}

    def restarted(self, key: tuple[str, str]) -> RobotRow | None:
        """The robot as last seen, once its agent has stopped it and started it again, or once
        the agent itself was started again since: a new agent process starts its robots anew,
        and counts restarts from 0."""
        row = self.seen.get(key)
        if row is None:
            return None
        agent, number = self.asked[key]
        when_asked, now = self.agents_asked.get(agent), self.agents_seen.get(agent)
        agent_anew = when_asked is not None and now is not None and now != when_asked
        return row if row.restarted >= number or agent_anew else None

    def back(self, key: tuple[str, str]) -> bool:
        """The robot was stopped and started again, and runs steadily."""
        row = self.restarted(key)
        return row is not None and row.state == "running" and _steady(row)

    def hopeless(self) -> bool:
        """A robot, started again, keeps failing: waiting longer would not help."""
        return any((row := self.restarted(key)) is not None and _stuck(row) for key in self.asked)

    @property
    def others_not_running(self) -> list[RobotRow]:
        """Robots that ran before the restart and do not now (none looked at without waiting)."""
        if not self.waited:
            return []
        rows = [
            self.seen.get(key) or RobotRow(*key, "robot", "", "gone", reason="not in status any more")
            for key in sorted(self.ran_before - set(self.asked))
        ]
        return [row for row in rows if row.state != "running"]

    @property
    def ok(self) -> bool:
        return not self.waited or (all(self.back(key) for key in self.asked) and not self.others_not_running)

    def to_json(self) -> dict[str, Any]:
        robots = []
        for (fleet, name), (agent, number) in self.asked.items():
            row = self.rows.get((fleet, name))
            robots.append(
                {
                    "fleet": fleet,
                    "name": name,
                    "agent": agent,
                    "restart": number,
                    "back": self.back((fleet, name)),
                    "state": row.state if row else None,
                    "reason": row.reason if row else "",
                }
            )
        others = [
            {"fleet": row.fleet, "name": row.name, "state": row.state, "reason": row.reason}
            for row in self.others_not_running
        ]
        return {
            "ok": self.ok,
            "waited": self.waited,
            "timed_out": self.timed_out,
            "robots": robots,
            "others_not_running": others,
        }


def restart(
    client: ControlClient,
    robots: list[str],
    fleet: str | None = None,
    wait: bool = True,
    timeout: float = 60.0,
    on_progress: Callable[[list[RobotRow]], None] | None = None,
) -> Restart:
    """Ask each robot's agent to stop it and start it again as deployed; with `wait`, follow them
    until each one is back and runs steadily, or will not by waiting (a node that keeps exiting),
    and the other robots of their fleets that ran before run again."""
    before = build_view(*client.status(fleet), time.time())
    located = {robot: robot_place(before, robot, fleet) for robot in dict.fromkeys(robots)}  # all found first
    fleets = {fleet_name for fleet_name, _ in located.values()}
    outcome = Restart(
        asked={},
        waited=wait,
        ran_before={(row.fleet, row.name) for row in before.robots if row.fleet in fleets and row.state == "running"},
        agents_asked={agent.name: agent.started_at for agent in before.agents if agent.online},
    )
    for robot, (fleet_name, agent) in located.items():
        reply = client.restart(agent, p.RestartRequest(fleet=fleet_name, robot=robot))
        outcome.asked[(fleet_name, robot)] = (agent, reply.restart)
        if reply.agent_started_at:  # the process that counts it (it may be newer than the one seen before)
            outcome.agents_asked[agent] = reply.agent_started_at
    deadline = time.monotonic() + timeout
    followed = set(outcome.asked) | outcome.ran_before
    asked_fleet = next(iter(fleets)) if len(fleets) == 1 else None
    while wait:
        view = build_view(*client.status(asked_fleet), time.time())
        outcome.seen = {(row.fleet, row.name): row for row in view.robots if row.fleet in fleets}
        outcome.agents_seen = {agent.name: agent.started_at for agent in view.agents if agent.online}
        if on_progress is not None:
            on_progress([row for key, row in outcome.seen.items() if key in followed])
        if outcome.ok or outcome.hopeless():
            break
        if time.monotonic() >= deadline:
            outcome.timed_out = True
            break
        time.sleep(POLL_INTERVAL)
    return outcome


def down(
    client: ControlClient, fleet: str, wait: bool = True, timeout: float = 30.0
) -> dict[str, p.ApplyReply | ControlError]:
    """Send every agent serving `fleet` an empty desired state (left with the router too, for
    agents away now) and forget the plan; with `wait`, return once the robots have stopped and the
    router holds the empty plan.  ControlError, nothing sent, for a fleet unknown here."""
    statuses, registries = fleet_status(client, fleet)
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
    # Until the router has taken the empty plan, a `fleet status` right after `fleet down` would
    # show the last plan's robots as pending.
    deadline = time.monotonic() + timeout
    while wait and time.monotonic() < deadline:
        statuses, registries = client.status(fleet)
        stopped = not any(status.robots for status in statuses if status.fleet == fleet)
        if stopped and _plan_taken(registries, fleet, generation):
            break
        time.sleep(POLL_INTERVAL)
    return replies
