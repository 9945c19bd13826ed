"""A deploy (or `fleet down`) made while an agent is away completes when the agent comes back,
with no second deploy: the router keeps each agent's latest desired state and the agent fetches
it when it connects (and every few seconds)."""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from fleet.client import down
from fleet.testing.control_plane import ROUTER
from fleet.testing.poll import poll
from fleet.wire import protocol as p
from tests.control.control_helpers import robot, wait_processes_gone

pytestmark = pytest.mark.integration


def test_deploy_while_an_agent_is_down_completes_when_it_returns(fresh_two_agents):
    cluster = fresh_two_agents
    first = cluster.deploy(cluster.spec())
    assert first.ok
    robot1_pids = robot(cluster.view("tiny"), "robot1").pids
    cluster.kill("agent-hostB", signal.SIGKILL)

    outcome = cluster.deploy(cluster.spec(), sets=["robot2.sleeper.period=2.0"], timeout=5)
    assert not outcome.ok and set(outcome.unreachable) == {"hostB"}

    cluster.start_agent("hostB")  # restores generation `first`, then fetches the newer one

    def deployed():
        view = cluster.view("tiny")
        rows = [row for row in view.robots if row.agent == "hostB"]
        return len(rows) == 2 and all(r.state == "running" and r.generation == outcome.generation for r in rows)

    poll(deployed, timeout=20, what="hostB's robots at the new generation", explain=lambda: cluster.log("agent-hostB"))
    params = (cluster.state_dir("hostB") / "units" / "tiny" / "robot2" / "robot2.params.yaml").read_text()
    assert "period: 2.0" in params
    assert robot(cluster.view("tiny"), "robot1").pids == robot1_pids  # hostA had nothing left to do

    # An older desired state put later (a slow deployer) changes nothing: the later generation wins.
    stale = p.ApplyRequest(
        fleet="tiny", agent="hostB", generation=first.generation, domain_id=cluster.domain_id, bundles=[]
    )
    with cluster.client() as client:
        client.put_desired([stale])
    cluster.kill("agent-hostB", signal.SIGTERM)
    cluster.start_agent("hostB")
    poll(
        deployed,
        timeout=20,
        what="hostB's robots still at the newer generation",
        explain=lambda: cluster.log("agent-hostB"),
    )


def test_down_while_an_agent_is_down_stops_its_robots_when_it_returns(fresh_two_agents):
    cluster = fresh_two_agents
    assert cluster.deploy(cluster.spec()).ok
    hostb_pids = set().union(*(row.pids for row in cluster.view("tiny").robots if row.agent == "hostB"))
    cluster.kill("agent-hostB", signal.SIGKILL)
    with cluster.client() as client:
        replies = down(client, "tiny")
    assert set(replies) == {"hostA"}  # hostB is away: only the router hears of it
    # The router keeps what it holds across a restart (its state directory).
    cluster.kill("router", signal.SIGTERM)
    cluster.start_router()
    wait_processes_gone(hostb_pids, 5)

    cluster.start_agent("hostB")  # restores robot2 and robot3, then fetches the empty desired state
    cluster.wait_agents_online("hostB")
    desired = cluster.state_dir("hostB") / "desired" / "tiny.json"
    poll(
        desired.read_text,
        until=lambda text: '"bundles":[]' in text,
        timeout=20,
        what="hostB to fetch the empty desired state",
        explain=lambda: cluster.log("agent-hostB"),
    )
    units = cluster.state_dir("hostB") / "units" / "tiny"
    poll(lambda: list(units.iterdir()), until=lambda left: not left, timeout=10, what="hostB's robots to stop")
    assert not cluster.view("tiny").robots


def test_bad_desired_states_are_ignored(fresh_two_agents):
    cluster = fresh_two_agents
    outcome = cluster.deploy(cluster.spec())
    assert outcome.ok, (outcome.replies, outcome.view and outcome.view.robots)
    before = cluster.view("tiny")
    newer = p.ApplyRequest(
        fleet="tiny", agent="hostA", generation=outcome.generation + 1, domain_id=cluster.domain_id, bundles=[]
    )
    with cluster.client() as client:
        client.session.put(p.desired_key("tiny", "hostB"), b"{not json")
        client.session.put(p.desired_key("tiny", "hostB"), p.encode(newer))  # hostA's, on hostB's key
        client.session.put(p.desired_key("other", "hostA"), p.encode(newer))  # fleet tiny on fleet other's key
        # The router refuses a malformed query with an error reply.
        replies = list(client.session.get(p.desired_key("*", "hostA"), payload=b"[1]", timeout=5))
        assert len(replies) == 1 and replies[0].err is not None
    cluster.kill("agent-hostB", signal.SIGTERM)  # and a fresh start fetches at once
    cluster.start_agent("hostB")
    cluster.wait_agents_online("hostB")
    poll(
        lambda: len(cluster.view("tiny").robots),
        until=lambda count: count == 3,
        timeout=15,
        what="three robots in status",
    )
    time.sleep(4)  # more than one fetch round
    # hostB's robot came back with hostB (its nodes started again: on a loaded machine an rclpy
    # node takes seconds to join the graph), and nothing else changed.
    after = poll(
        lambda: cluster.view("tiny"),
        until=lambda view: all(r.state == "running" for r in view.robots),
        timeout=60,
        interval=0.5,
        what="every robot running again",
    )
    assert [(r.name, r.state, r.generation) for r in after.robots] == [
        (r.name, r.state, r.generation) for r in before.robots
    ]
    assert "ignoring desired state" in cluster.log("router")


def test_the_router_ends_every_desired_state_answer(fresh_cluster):
    """It always adds a DesiredDone reply, also when nothing is newer: an agent that gets no reply at all
    knows its session has stalled (fleet.server.agent), not that nothing changed."""
    cluster = fresh_cluster
    cluster.start_router()
    stored = p.ApplyRequest(fleet="tiny", agent="hostA", generation=7, domain_id=cluster.domain_id, bundles=[])
    with cluster.client() as client:

        def answer(held: dict[str, int]) -> list[tuple[str, str]]:
            query = p.encode(p.DesiredQuery(held=held))
            replies = client.session.get(p.desired_key("*", "hostA"), payload=query, timeout=5)
            return [(str(r.ok.key_expr), r.ok.payload.to_bytes().decode()) for r in replies if r.ok is not None]

        # The router subscribes to desired states before it answers queries: once it answers, a put lands.
        poll(lambda: answer({}), until=bool, timeout=10, what="the router to answer")
        client.put_desired([stored])
        newer = poll(lambda: answer({"tiny": 6}), until=lambda replies: len(replies) == 2, timeout=10, what="2 replies")
        by_key = dict(newer)  # Zenoh does not keep the order of one query's replies
        assert set(by_key) == {p.desired_key("tiny", "hostA"), p.desired_key("*", "hostA")}
        assert p.decode(by_key[p.desired_key("tiny", "hostA")].encode(), p.ApplyRequest).generation == 7
        assert p.decode(by_key[p.desired_key("*", "hostA")].encode(), p.DesiredDone).sent == 1
        nothing_newer = answer({"tiny": 7})
        assert [key for key, _ in nothing_newer] == [p.desired_key("*", "hostA")]
        assert p.decode(nothing_newer[0][1].encode(), p.DesiredDone).sent == 0
        # A query for one fleet (as the dashboard asks for a robot's deployed parameters) gets
        # only the state, which then is the one and only reply.
        query = p.encode(p.DesiredQuery(held={"tiny": 0}))
        with_fleet = client.session.get(p.desired_key("tiny", "hostA"), payload=query, timeout=5)
        assert [str(r.ok.key_expr) for r in with_fleet if r.ok is not None] == [p.desired_key("tiny", "hostA")]


def test_a_plan_put_right_after_a_deploy_s_desired_states_reaches_the_router(fresh_cluster):
    """A deploy puts each agent's desired state, then the plan, back to back.  With Zenoh's
    default for puts (dropped when the send queue is still full a millisecond later) the plan
    was lost behind large desired states about one deploy in five on a busy machine, and
    `fleet deploy` waited for it until its timeout.  Here the router is frozen for a second while
    they are sent (a busy machine, exaggerated): the puts must wait for it, not be dropped."""
    cluster = fresh_cluster
    cluster.start_router()
    router = cluster.pid(ROUTER)
    assert router is not None
    # 100 agents' desired states of 50 KB each (a robot's parameters and launch files make tens
    # of KiB), then the plan.  Built unchecked: the router ignores them, only the send queue matters.
    states = [
        p.ApplyRequest.model_construct(
            fleet="tiny", agent=f"agent{index}", generation=7, domain_id=1, bundles=[], discovery_host="x" * 50_000
        )
        for index in range(100)
    ]
    plan = p.PlanRecord(fleet="tiny", generation=7, robots={"robot1": "agent0"}, deployed_at=time.time())
    with cluster.client() as client:
        poll(lambda: client.status("tiny")[1], until=bool, timeout=10, what="the router's registry to answer")
        os.kill(router, signal.SIGSTOP)
        thaw = threading.Timer(1.0, os.kill, (router, signal.SIGCONT))
        thaw.start()
        try:
            client.put_desired(states)
            client.put_plan(plan)
        finally:
            thaw.join()

        def plans_held() -> list[int]:
            return [record.generation for reply in client.status("tiny")[1] for record in reply.history]

        assert poll(plans_held, until=bool, timeout=10, what="the router to hold the plan") == [7]
