"""isolation: agent over the control plane: several robots' fleet nodes in shared host processes of
one agent, seen from rclpy and from the CLI (status, logs, param); a robot's fault, removal and
parameter change stay its own."""

from __future__ import annotations

import json
import socket

import psutil
import pytest

from fleet.testing.poll import poll
from fleet.testing.ros import RosProbe
from tests.control.control_helpers import robot

pytestmark = pytest.mark.integration

ROBOTS = ["robot1", "robot2", "robot3"]
HOSTED = {"controller", "battery"}


def hosted_spec(cluster, robots: list[str], speeds: dict[str, float] | None = None):
    return cluster.spec(
        name="hosted",
        fleet="hosted",
        defaults={"template": "hosted", "agent": "hostA", "isolation": "agent", "group_size": 2},
        robots=[
            {"name": name, "parameters": {"controller": {"max_speed": (speeds or {}).get(name, speed(name))}}}
            for name in robots
        ],
    )


def speed(name: str) -> float:
    return 0.1 * int(name.removeprefix("robot"))


def snapshot(view) -> dict[str, dict]:
    """robot -> node -> (state, pid, restarts)."""
    return {
        row.name: {node["name"]: (node["state"], node["pid"], node["restarts"]) for node in row.nodes}
        for row in view.robots
    }


def fault(pid: int, robot_name: str, node: str) -> dict:
    """The host's fault hook (see fleet.nodes.host): that node's next timer callback raises."""
    arguments = psutil.Process(pid).cmdline()
    control = arguments[arguments.index("--control") + 1]
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as connection:
        connection.connect(control)
        stream = connection.makefile("rwb")
        stream.write(json.dumps({"op": "fault", "robot": robot_name, "node": node}).encode() + b"\n")
        stream.flush()
        return json.loads(stream.readline())


def test_robots_hosted_by_their_agent(fresh_cluster):
    cluster = fresh_cluster
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.wait_agents_online("hostA")
    outcome = cluster.deploy(hosted_spec(cluster, ROBOTS), timeout=90)
    assert outcome.ok, (outcome.view and outcome.view.robots, cluster.log("agent-hostA"))
    view = cluster.view("hosted")
    before = snapshot(view)
    assert set(before) == set(ROBOTS)
    for name in ROBOTS:
        row = robot(view, name)
        assert row.state == "running" and row.running == row.total == 3, row
    # Two robots per host (group_size 2): robot1 and robot2 share a host process, robot3 has its
    # own; the sleeper (not composable) is a process of its own in every robot.
    host12 = {before[name][node][1] for name in ("robot1", "robot2") for node in HOSTED}
    host3 = {before["robot3"][node][1] for node in HOSTED}
    assert len(host12) == 1 and len(host3) == 1 and host12 != host3
    sleepers = {before[name]["sleeper"][1] for name in ROBOTS}
    assert len(sleepers) == 3 and not sleepers & (host12 | host3)

    (discovery,) = view.discovery["hosted"]
    with RosProbe("hosted_probe", domain_id=cluster.domain_id, discovery_server=discovery["server"]) as probe:
        probe.wait_for_nodes({f"/{name}/{node}" for name in ROBOTS for node in HOSTED}, timeout=30)
        for index, name in enumerate(ROBOTS):
            assert probe.get_parameters(f"/{name}/controller", ["max_speed"]) == pytest.approx([0.1 * (index + 1)])
            assert probe.get_parameters(f"/{name}/battery", ["capacity"]) == [50.0]
        assert "/robot2/cmd_vel_nav" in probe.topics()

    # `fleet param` reaches a hosted node; the change stays with that robot.
    param_set = cluster.cli("param", "set", "robot2", "controller", "max_speed", "0.9", "--connect", cluster.endpoint)
    assert param_set.returncode == 0, param_set.stdout + param_set.stderr
    got = cluster.cli("param", "get", "robot2", "controller", "max_speed", "--connect", cluster.endpoint)
    assert got.returncode == 0 and json.loads(got.stdout) == 0.9, got.stdout + got.stderr
    other = cluster.cli("param", "get", "robot1", "controller", "max_speed", "--connect", cluster.endpoint)
    assert json.loads(other.stdout) == pytest.approx(0.1)
    # Each hosted node lists its own parameters, as a node of its own process would, and so does
    # the sleeper in its process beside the host.
    listed = cluster.cli("param", "list", "robot2", "--json", "--connect", cluster.endpoint)
    assert listed.returncode == 0, listed.stdout + listed.stderr
    parameters = json.loads(listed.stdout)["parameters"]
    assert parameters["controller"]["max_speed"] == 0.9 and parameters["battery"]["capacity"] == 50.0
    assert "max_speed" not in parameters["battery"] and parameters["sleeper"]["period"] == 1.0
    assert snapshot(cluster.view("hosted")) == before  # nothing restarted

    # robot2's controller raises in a callback: robot2's hosted nodes restart (same host), the
    # others keep their pids and restart counts.
    assert fault(before["robot2"]["controller"][1], "robot2", "controller") == {"ok": True}
    poll(
        lambda: snapshot(cluster.view("hosted"))["robot2"]["controller"],
        until=lambda node: node[0] == "running" and node[2] == 1,
        timeout=30,
        what="robot2's controller restarted once",
    )
    after = snapshot(cluster.view("hosted"))
    assert after["robot1"] == before["robot1"] and after["robot3"] == before["robot3"]
    assert after["robot2"]["controller"][1] == before["robot2"]["controller"][1]
    assert robot(cluster.view("hosted"), "robot2").restarts >= 1
    poll(
        lambda: robot(cluster.view("hosted"), "robot2").state,
        until=lambda state: state == "running",
        timeout=30,
        what="robot2 running again",
    )

    # `fleet logs ROBOT NODE`: the traceback is in robot2's controller log, not in robot1's.
    logs = cluster.cli("logs", "robot2", "controller", "--connect", cluster.endpoint, "--tail", "200")
    assert logs.returncode == 0 and "fault injected into /robot2/controller" in logs.stdout, logs.stdout + logs.stderr
    assert "started:" in logs.stdout and "max_speed=" in logs.stdout
    quiet = cluster.cli("logs", "robot1", "controller", "--connect", cluster.endpoint, "--tail", "200")
    assert quiet.returncode == 0 and "started:" in quiet.stdout and "fault injected" not in quiet.stdout
    sleeper = cluster.cli("logs", "robot1", "sleeper", "--connect", cluster.endpoint)
    assert "sleeper started" in sleeper.stdout or "tick" in sleeper.stdout, sleeper.stdout + sleeper.stderr

    # A redeploy removing robot1 and adding robot4 touches neither robot2 nor robot3; robot4
    # takes robot1's place in robot2's host.
    outcome = cluster.deploy(hosted_spec(cluster, ["robot2", "robot3", "robot4"]), timeout=60)
    assert outcome.ok, outcome.view and outcome.view.robots
    poll(
        lambda: snapshot(cluster.view("hosted")),
        until=lambda rows: (
            set(rows) == {"robot2", "robot3", "robot4"} and {node[0] for node in rows["robot4"].values()} == {"running"}
        ),
        timeout=30,
        what="robot1 removed, robot4 running",
    )
    final = snapshot(cluster.view("hosted"))
    assert final["robot2"] == after["robot2"] and final["robot3"] == after["robot3"]
    assert {final["robot4"][node][1] for node in HOSTED} == host12
    # The parameter set on robot2 survived: its nodes were not recreated.
    got = cluster.cli("param", "get", "robot2", "controller", "max_speed", "--connect", cluster.endpoint)
    assert json.loads(got.stdout) == 0.9

    # A redeploy changing robot3's parameters restarts robot3 alone, with its new value.
    changed = hosted_spec(cluster, ["robot2", "robot3", "robot4"], speeds={"robot3": 0.75})
    outcome = cluster.deploy(changed, timeout=60)
    assert outcome.ok, outcome.view and outcome.view.robots
    got = cluster.cli("param", "get", "robot3", "controller", "max_speed", "--connect", cluster.endpoint)
    assert got.returncode == 0 and json.loads(got.stdout) == 0.75, got.stdout + got.stderr
    last = snapshot(cluster.view("hosted"))
    assert last["robot2"] == final["robot2"] and last["robot4"] == final["robot4"]
