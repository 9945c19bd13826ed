"""The router dies under a running fleet and comes back: the robots never stop, the agents are
back within 3 s of the router listening again, and the fleet's desired state is intact (a later
deploy of the same spec changes nothing, and an agent restarted afterwards gets its robots)."""

from __future__ import annotations

import shutil
import signal
import time

import psutil
import pytest

from fleet.testing.control_plane import ROUTER
from fleet.testing.poll import poll

pytestmark = pytest.mark.integration

RECONNECT_WITHIN_S = 3.0


def node_pids(view) -> dict[str, set[int]]:
    return {row.name: set(row.pids) for row in view.robots}


def test_robots_keep_running_and_agents_reconnect_when_the_router_restarts(fresh_two_agents):
    cluster = fresh_two_agents
    first = cluster.deploy(cluster.spec())
    assert first.ok
    before = cluster.view("tiny")
    pids = node_pids(before)
    assert len(pids) == 3 and all(pids.values())

    cluster.kill("router", signal.SIGKILL)
    time.sleep(3)  # longer than the agents' 2 s link lease: they have noticed the router is gone
    assert all(psutil.pid_exists(pid) for group in pids.values() for pid in group)

    cluster.start_router()  # returns once the router answers status queries
    listening = time.monotonic()

    def both_agents_back():
        agents = {a.name: a.online for a in cluster.view("tiny").agents}
        return agents.get("hostA") and agents.get("hostB")

    poll(
        both_agents_back, timeout=15, interval=0.05, what="both agents back", explain=lambda: cluster.log("agent-hostA")
    )
    reconnected = time.monotonic() - listening
    assert reconnected < RECONNECT_WITHIN_S, f"agents took {reconnected:.1f} s to reconnect"

    after = cluster.view("tiny")
    assert node_pids(after) == pids  # the same processes throughout: nothing restarted
    assert [(r.name, r.agent, r.generation) for r in after.robots] == [
        (r.name, r.agent, r.generation) for r in before.robots
    ]

    # The router's desired state survived: an agent that restarts now gets its robots back from
    # it, and redeploying the same spec is a no-op for everyone.
    hostb = {name for name, row in ((r.name, r) for r in after.robots) if row.agent == "hostB"}
    cluster.kill("agent-hostB", signal.SIGKILL)
    cluster.start_agent("hostB")
    cluster.wait_agents_online("hostB")

    def hostb_restored():
        rows = [r for r in cluster.view("tiny").robots if r.agent == "hostB"]
        return {r.name for r in rows} == hostb and all(r.generation == first.generation for r in rows)

    poll(hostb_restored, timeout=20, what="hostB's robots restored", explain=lambda: cluster.log("agent-hostB"))
    again = cluster.deploy(cluster.spec())
    assert again.ok
    hosta_pids = {name: group for name, group in pids.items() if name not in hostb}
    assert {name: group for name, group in node_pids(cluster.view("tiny")).items() if name not in hostb} == hosta_pids


def test_a_no_op_redeploy_gives_a_router_that_lost_its_records_the_plan_again(fresh_two_agents):
    """A router started again without its state directory knows nothing of what runs where; a
    redeploy of the same spec changes nothing on the agents, and gives the router its records
    again: an agent that then goes away still shows its robots, offline."""
    cluster = fresh_two_agents
    first = cluster.deploy(cluster.spec())
    assert first.ok
    cluster.kill("router", signal.SIGKILL)
    shutil.rmtree(cluster.root / ROUTER)
    cluster.start_router()
    cluster.wait_agents_online("hostA", "hostB")

    again = cluster.deploy(cluster.spec())
    assert again.ok and again.nothing_changed and again.generation == first.generation
    with cluster.client() as client:
        _, registries = client.status("tiny")
    assert [plan.generation for registry in registries for plan in registry.history if registry.fleet == "tiny"] == [
        first.generation
    ]
    cluster.kill("agent-hostB", signal.SIGKILL)
    view = poll(
        lambda: cluster.view("tiny"),
        until=lambda view: any(a.name == "hostB" and not a.online for a in view.agents),
        timeout=10,
        what="hostB shown offline",
    )
    assert {row.name: row.state for row in view.robots if row.agent == "hostB"} == {
        "robot2": "offline",
        "robot3": "offline",
    }
