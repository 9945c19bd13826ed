"""fleets/two_robots.yaml over the control plane with real nodes: one robot per agent."""

from __future__ import annotations

import json
import signal
import time

import pytest
import yaml

from fleet.testing.poll import poll
from tests.checkout import FLEETS
from tests.control.control_helpers import Cluster, robot, wait_processes_gone

pytestmark = pytest.mark.integration


@pytest.fixture(scope="module")
def two_robots(tmp_path_factory, domain_id):
    cluster = Cluster(tmp_path_factory.mktemp("two_robots"), domain_id)
    data = yaml.safe_load((FLEETS / "two_robots.yaml").read_text())
    data["ros"]["domain_id"] = domain_id
    data["agents"] = {"hostA": {}, "hostB": {}}
    data["defaults"]["agent"] = "hostA"
    data["world"]["agent"] = "hostA"
    next(r for r in data["robots"] if r["name"] == "robot2")["agent"] = "hostB"
    spec = cluster.root / "two_robots.yaml"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    try:
        cluster.start_router()
        cluster.start_agent("hostA")
        cluster.start_agent("hostB")
        cluster.wait_agents_online("hostA", "hostB")
        cluster.spec_file = spec
        yield cluster
    finally:
        cluster.stop()


def deployed(cluster: Cluster) -> Cluster:
    """The fleet running as its spec says, whichever tests ran before this one (with none, or on
    another xdist worker, it starts here; already so, the deploy changes nothing)."""
    done = cluster.cli("deploy", str(cluster.spec_file), "--connect", cluster.endpoint, "--timeout", "90", timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    return cluster


def pids(view) -> dict[str, set[int]]:
    return {row.name: row.pids for row in view.robots}


def test_deploy_status_and_noop_redeploy(two_robots):
    cluster = two_robots
    done = cluster.cli("deploy", str(cluster.spec_file), "--connect", cluster.endpoint, "--timeout", "90", timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr + cluster.log("agent-hostA")
    view = cluster.view("two_robots")
    assert {row.name: row.agent for row in view.robots} == {"world": "hostA", "robot1": "hostA", "robot2": "hostB"}
    for name in ("robot1", "robot2"):
        row = robot(view, name)
        assert row.state == "running" and row.running == row.total >= 2
        assert {node["name"] for node in row.nodes} >= {"controller", "battery"}

    # The world's status file reaches `fleet status`: poses (and battery) per robot.
    def posed():
        view = cluster.view("two_robots")
        return all(robot(view, name).pose for name in ("robot1", "robot2")) and view

    poll(
        posed, timeout=30, what="poses of both robots in status", explain=lambda: str(cluster.view("two_robots").robots)
    )
    before = pids(cluster.view("two_robots"))
    again = cluster.cli("deploy", str(cluster.spec_file), "--connect", cluster.endpoint)
    assert again.returncode == 0 and "nothing changed" in again.stdout, again.stdout
    assert pids(cluster.view("two_robots")) == before


def test_status_of_one_robot_shows_it_and_its_nodes(two_robots):
    """`fleet status robot2`, as `kubectl get pod NAME`: that robot, its agent, a row per node."""
    cluster = deployed(two_robots)
    shown = cluster.cli("status", "robot2", "--connect", cluster.endpoint)
    assert shown.returncode == 0, shown.stdout + shown.stderr
    lines = shown.stdout.splitlines()
    assert [line.split()[0] for line in lines[lines.index("Agents") + 3 : lines.index("Robots")]] == ["hostB"]
    assert [line.split()[0] for line in lines[lines.index("Robots") + 3 : lines.index("Nodes")]] == ["robot2"]
    rows = {line.split()[1]: line.split() for line in lines[lines.index("Nodes") + 3 :] if line.startswith("robot2 ")}
    nodes = {node["name"]: node for node in robot(cluster.view("two_robots"), "robot2").nodes}
    assert set(rows) == set(nodes)
    for name, row in rows.items():
        assert row[2] == "running" and int(row[3]) == nodes[name]["pid"], row
    assert "world two_robots on hostA" in shown.stdout  # its fleet's world

    as_json = json.loads(cluster.cli("status", "robot2", "--json", "--connect", cluster.endpoint).stdout)
    assert [row["name"] for row in as_json["robots"]] == ["robot2"]
    assert {node["name"] for node in as_json["robots"][0]["nodes"]} == set(nodes)

    unknown = cluster.cli("status", "robot2", "robot9", "--connect", cluster.endpoint)
    assert unknown.returncode == 2 and unknown.stdout == "", unknown.stdout + unknown.stderr
    assert unknown.stderr.splitlines() == [
        "fleet: error: <command line>: no robot named 'robot9' is deployed (robots: robot1, robot2, world)"
    ]


def test_set_on_robot2_restarts_only_robot2_and_reaches_the_node(two_robots):
    cluster = deployed(two_robots)
    before = pids(cluster.view("two_robots"))
    done = cluster.cli(
        "deploy",
        str(cluster.spec_file),
        "--set",
        "robot2.controller.max_speed=0.9",
        "--connect",
        cluster.endpoint,
        "--timeout",
        "90",
        timeout=120,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    after = pids(cluster.view("two_robots"))
    assert after["robot1"] == before["robot1"] and after["world"] == before["world"]
    assert after["robot2"].isdisjoint(before["robot2"])
    got = cluster.cli("param", "get", "robot2", "controller", "max_speed", "--connect", cluster.endpoint)
    assert got.returncode == 0, got.stderr
    assert json.loads(got.stdout) == 0.9


def test_live_parameter_set_is_checked_and_kept(two_robots):
    cluster = deployed(two_robots)
    refused = cluster.cli("param", "set", "robot1", "controller", "max_speed", "99", "--connect", cluster.endpoint)
    assert refused.returncode == 2 and "refused" in refused.stderr, refused.stderr  # the value: bad input
    # A value of another type: the node's refusal in the words of a parameter file.
    mistyped = cluster.cli("param", "set", "robot1", "controller", "loop", "maybe", "--connect", cluster.endpoint)
    assert mistyped.returncode == 2, mistyped.stdout + mistyped.stderr
    assert "refused loop=maybe: it holds a bool (true or false), and the value given is a string" in mistyped.stderr
    accepted = cluster.cli("param", "set", "robot1", "controller", "max_speed", "0.7", "--connect", cluster.endpoint)
    assert accepted.returncode == 0, accepted.stderr
    got = cluster.cli("param", "get", "robot1", "controller", "max_speed", "--connect", cluster.endpoint)
    assert json.loads(got.stdout) == 0.7
    desired = json.loads((cluster.state_dir("hostA") / "desired" / "two_robots.json").read_text())
    assert desired["overrides"]["robot1"]["/robot1/controller"]["max_speed"] == 0.7
    params = (cluster.state_dir("hostA") / "units" / "two_robots" / "robot1" / "robot1.params.yaml").read_text()
    assert yaml.safe_load(params)["/robot1/controller"]["ros__parameters"]["max_speed"] == 0.7
    diff = cluster.cli(
        "diff",
        str(cluster.spec_file),
        "--set",
        "robot2.controller.max_speed=0.9",
        "--json",
        "--connect",
        cluster.endpoint,
    )
    row = next(r for r in json.loads(diff.stdout) if r["robot"] == "robot1")
    assert row["change"] == "unchanged" and "max_speed=0.7" in row["detail"]
    restart = cluster.cli(
        "diff", str(cluster.spec_file), "--set", "robot1.battery.capacity=40.0", "--json", "--connect", cluster.endpoint
    )
    row = next(r for r in json.loads(restart.stdout) if r["robot"] == "robot1")
    assert row["change"] == "restart", row
    assert row["detail"] == "battery.capacity 50.0 -> 40.0; live overrides dropped: /robot1/controller max_speed=0.7"


def test_killed_agent_goes_offline_and_comes_back(two_robots):
    cluster = deployed(two_robots)
    robot2_pids = robot(cluster.view("two_robots"), "robot2").pids
    cluster.kill("agent-hostB", signal.SIGKILL)
    started = time.monotonic()

    def offline():
        view = cluster.view("two_robots")
        return robot(view, "robot2").state == "offline" and view

    poll(offline, timeout=3.0, what="robot2 shown offline after its agent's SIGKILL")
    assert time.monotonic() - started < 3.0
    wait_processes_gone(robot2_pids, 3.0)
    cluster.start_agent("hostB")

    def restored():
        row = robot(cluster.view("two_robots"), "robot2")
        return row.state == "running" and row.running == row.total

    poll(restored, timeout=60, what="robot2 running again", explain=lambda: cluster.log("agent-hostB"))
