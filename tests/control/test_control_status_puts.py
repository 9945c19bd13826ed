"""What a watcher (`fleet dashboard`) gets from the control plane: agents put their status while
someone subscribes, and the router keeps the fleet's generation history, across its restarts."""

from __future__ import annotations

import itertools
import signal
import threading
import time

import pytest

from fleet.control import protocol as p
from fleet.control.deploy import down
from fleet.testing.poll import poll

pytestmark = pytest.mark.integration


def test_agents_publish_status_to_subscribers(cluster):
    outcome = cluster.deploy(cluster.spec())
    assert outcome.ok
    received: list[tuple[float, str, p.StatusReply]] = []
    lock = threading.Lock()

    def on_status(sample) -> None:
        with lock:
            received.append(
                (time.monotonic(), str(sample.key_expr), p.decode(sample.payload.to_bytes(), p.StatusReply))
            )

    with cluster.client() as client:
        subscriber = client.session.declare_subscriber(p.agent_status_key("tiny", "*"), on_status)
        try:
            time.sleep(2.0)
        finally:
            subscriber.undeclare()
    with lock:
        by_agent = {
            agent: [r for r in received if r[1] == p.agent_status_key("tiny", agent)] for agent in ("hostA", "hostB")
        }
    for agent, replies in by_agent.items():
        assert len(replies) >= 4, (agent, len(replies))  # every 0.25 s, a match takes a moment
        times = [when for when, _, _ in replies]
        assert max(b - a for a, b in itertools.pairwise(times)) < 1.0, times  # a change shows within 1 s
        status = replies[-1][2]
        assert (status.agent.name, status.fleet, status.generation) == (agent, "tiny", outcome.generation)
        assert {robot.name for robot in status.robots} == {
            row.name for row in cluster.view("tiny").robots if row.agent == agent
        }


def test_router_keeps_the_generation_history_across_restarts(fresh_cluster):
    cluster = fresh_cluster
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.start_agent("hostB")
    cluster.wait_agents_online("hostA", "hostB")
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
