"""Pure tests of which fleets a router and its agents know: what `fleet status --fleet` and
`fleet down --fleet` accept, so that a mistyped name is an error, not an empty fleet."""

from __future__ import annotations

from fleet.plan import known_fleets
from fleet.wire import protocol as p


def serving(fleet: str | None, agent: str = "a") -> p.StatusReply:
    info = p.AgentInfo(name=agent, hostname=agent, cores=2, pid=1, version="0", started_at=0.0)
    return p.StatusReply(agent=info, fleet=fleet, time=0.0)


def plan(fleet: str, robots: dict[str, str]) -> p.PlanRecord:
    return p.PlanRecord(fleet=fleet, generation=1, robots=robots, deployed_at=0.0)


def test_served_planned_and_seen_fleets_are_known():
    registries = [
        p.RegistryReply(fleet="planned", plan=plan("planned", {"r1": "a"})),
        p.RegistryReply(fleet="seen", agents={"a": p.AgentSeen(online=False, last_seen=0.0)}),
    ]
    assert known_fleets([serving("served"), serving(None, "idle")], registries) == ["planned", "seen", "served"]


def test_the_registry_answer_for_any_name_and_a_taken_down_fleets_history_are_not():
    # The router answers a registry query for whatever name it is asked, and after `fleet down`
    # it keeps only the fleet's history.
    registries = [
        p.RegistryReply(fleet="typo"),
        p.RegistryReply(fleet="gone", history=[plan("gone", {"r1": "a"}), plan("gone", {})]),
    ]
    assert known_fleets([serving(None)], registries) == []
