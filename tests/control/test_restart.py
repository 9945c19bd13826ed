"""`fleet restart ROBOT...` over the control plane, with fleets/two_robots.yaml's real nodes and
world: the robot's nodes stop and start again as deployed (parameters set live kept), the other
robot's nodes are not touched, the world resumes its time, and the command waits until each one
runs again; whichever isolation runs them.  An unknown robot is bad input."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest

from fleet.client import restart as restart_robots
from fleet.testing.control_plane import agent_key
from tests.control.control_helpers import Cluster

pytestmark = pytest.mark.integration


def deploy(cluster: Cluster, isolation: str) -> None:
    done = fleet(cluster, "deploy", str(cluster.two_robots_on_host_a(isolation)), "--timeout", "150", timeout=200)
    assert done.returncode == 0, done.stdout + done.stderr


def fleet(cluster: Cluster, *args: str, timeout: float = 120):
    return cluster.cli(*args, "--connect", cluster.endpoint, timeout=timeout)


def status(cluster: Cluster) -> dict:
    shown = fleet(cluster, "status", "--json", "--fleet", "two_robots")
    assert shown.returncode == 0, shown.stdout + shown.stderr
    return json.loads(shown.stdout)


def rows(document: dict) -> dict[str, dict]:
    return {row["name"]: row for row in document["robots"]}


def restart(cluster: Cluster, *robots: str) -> dict:
    done = fleet(cluster, "restart", *robots, "--json", "--timeout", "100")
    outcome = json.loads(done.stdout)
    assert done.returncode == 0 and outcome["ok"], done.stdout + done.stderr
    return outcome


def test_a_restarted_robot_runs_again_with_new_processes_and_its_live_parameters(host_a):
    cluster = host_a
    deploy(cluster, "process")
    assert fleet(cluster, "param", "set", "robot1", "controller", "max_speed", "0.3").returncode == 0
    before = rows(status(cluster))

    outcome = restart(cluster, "robot1")
    assert [(r["name"], r["agent"], r["restart"], r["back"]) for r in outcome["robots"]] == [
        ("robot1", "hostA", 1, True)
    ]
    after = rows(status(cluster))
    assert after["robot1"]["state"] == "running" and after["robot1"]["restarted"] == 1, after["robot1"]
    old = {node["pid"] for node in before["robot1"]["nodes"]}
    new = {node["pid"] for node in after["robot1"]["nodes"]}
    assert len(new) == 3 and not old & new, (old, new)
    assert [node["pid"] for node in after["robot2"]["nodes"]] == [node["pid"] for node in before["robot2"]["nodes"]]
    assert after["robot2"]["restarted"] == 0
    got = fleet(cluster, "param", "get", "robot1", "controller", "max_speed")
    assert got.stdout.strip() == "0.3", got.stdout + got.stderr

    # The world too: it resumes from its last time, and the robots keep running in it.
    sim_time = status(cluster)["worlds"][0]["sim_time"]
    restart(cluster, "world")
    again = status(cluster)
    assert again["worlds"][0]["sim_time"] >= sim_time and rows(again)["world"]["restarted"] == 1, again["worlds"]

    # A robot nobody deployed: bad input, one line, nothing restarted.
    unknown = fleet(cluster, "restart", "robot1", "robot9")
    assert unknown.returncode == 2 and unknown.stderr.count("\n") == 1, unknown.stdout + unknown.stderr
    assert "no robot named 'robot9' is deployed" in unknown.stderr
    assert rows(status(cluster))["robot1"]["restarted"] == 1


def test_logs_followed_across_a_restart_go_on_with_how_the_old_processes_ended(host_a):
    """`fleet logs ROBOT NODE -f` and `fleet logs ROBOT -f` while the robot is restarted: its
    nodes are down for a moment, and the followers neither end (the node is not unknown) nor
    lose their place (the old processes' last lines and the new ones' first come once)."""
    cluster = host_a
    deploy(cluster, "process")
    followers = {
        which: subprocess.Popen(
            [sys.executable, "-m", "fleet", "logs", "robot1", *node, "-f", "-n", "1", "--connect", cluster.endpoint],
            env=cluster.env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for which, node in (("controller", ["controller"]), ("robot", []))
    }
    try:
        time.sleep(3)  # each has read its tail and follows
        restart(cluster, "robot1")
        time.sleep(3)  # the new processes' first lines
        exited = {which: process.poll() for which, process in followers.items()}
    finally:
        for process in followers.values():
            process.terminate()
    output = {which: process.communicate(timeout=10) for which, process in followers.items()}
    assert exited == {"controller": None, "robot": None}, (exited, output)
    for which, (out, _) in output.items():
        ended = [line for line in out.splitlines() if "controller-1]: process has finished cleanly" in line]
        started = [line for line in out.splitlines() if "controller-1]: process started with pid" in line]
        assert len(ended) == 1 and len(started) == 1, (which, out)
        assert out.index(ended[0]) < out.index(started[0]), (which, out)


def test_a_restart_ends_when_its_agent_was_started_again_meanwhile(host_a):
    """The agent is SIGKILLed and started again right after it answered: the new agent process
    counts restarts from 0, so the number it answered never comes; it starts its robots anew
    instead, and the restart ends once they run under it."""
    cluster = host_a
    deploy(cluster, "process")
    old_pids = {node["pid"] for node in rows(status(cluster))["robot1"]["nodes"]}
    agents_killed: list[int] = []

    def agent_restarts(_rows) -> None:
        if not agents_killed:
            agents_killed.append(cluster.kill(agent_key("hostA"), signal.SIGKILL))
            cluster.start_agent("hostA")

    with cluster.client() as control:
        outcome = restart_robots(control, ["robot1"], timeout=150, on_progress=agent_restarts)
    assert agents_killed and not outcome.timed_out, outcome.to_json()
    assert outcome.ok, outcome.to_json()
    after = rows(status(cluster))
    assert after["robot1"]["state"] == "running" and after["robot1"]["restarted"] == 0, after["robot1"]
    assert not old_pids & {node["pid"] for node in after["robot1"]["nodes"]}


def test_a_restarted_hosted_robot_is_made_again_in_its_host_and_no_other_is(host_a):
    cluster = host_a
    deploy(cluster, "agent")
    before = rows(status(cluster))
    outcome = restart(cluster, "robot2")
    assert [(r["name"], r["back"]) for r in outcome["robots"]] == [("robot2", True)]
    after = rows(status(cluster))
    # One host process runs both robots: robot2's nodes are made again in it, robot1's run on.
    assert {node["pid"] for node in after["robot2"]["nodes"]} == {node["pid"] for node in before["robot2"]["nodes"]}
    assert min(node["uptime"] for node in after["robot1"]["nodes"]) > max(
        node["uptime"] for node in after["robot2"]["nodes"]
    ), (after["robot1"]["nodes"], after["robot2"]["nodes"])
    assert after["robot2"]["restarted"] == before["robot2"]["restarted"] + 1
    assert after["robot1"]["restarted"] == before["robot1"]["restarted"]
