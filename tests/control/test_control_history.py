"""What a watcher (`fleet dashboard`) gets from the control plane besides status: the router
keeps the fleet's generation history, across its restarts."""

from __future__ import annotations

import signal

import pytest

from fleet.client import down
from fleet.testing.poll import poll

pytestmark = pytest.mark.integration


def test_router_keeps_the_generation_history_across_restarts(fresh_two_agents):
    cluster = fresh_two_agents
    first = cluster.deploy(cluster.spec())
    second = cluster.deploy(cluster.spec(), sets=["robot2.sleeper.period=2.0"])
    assert first.ok and second.ok
    with cluster.client() as client:
        down(client, "tiny", timeout=20)

    def history() -> list[tuple[int, list[str]]]:
        with cluster.client() as client:
            registries = [r for r in client.status("tiny")[1] if r.fleet == "tiny"]
        return [(plan.generation, sorted(plan.robots)) for plan in registries[0].history] if registries else []

    expected = history()  # oldest first: both deploys, then the `fleet down` (no robots)
    assert [generation for generation, _ in expected][:2] == [first.generation, second.generation]
    assert len(expected) == 3 and expected[2][1] == []
    assert {"robot1", "robot2"} <= set(expected[0][1]) and expected[0][1] == expected[1][1]

    cluster.kill("router", signal.SIGTERM)
    cluster.start_router()
    poll(history, until=lambda held: held == expected, timeout=10, what=f"the generation history {expected}")
