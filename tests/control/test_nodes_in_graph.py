"""A robot runs when its ROS nodes are in the ROS graph, as its agent's watch (a discovery super
client) sees it, not when their processes merely run: in a fleet without a world (no data for
fleet to watch) and in one with a world (whose data shows only the nodes it talks to).  Real
processes, real DDS: the stand-in sleeper is an rclpy node, the world is PyBullet's."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
import yaml

from fleet.testing.poll import poll
from tests.checkout import REPO
from tests.control.control_helpers import DATA

pytestmark = pytest.mark.integration

# A `node` whose process runs and never joins the ROS graph, as one stuck before or in creating
# its node (SIGKILLed participants' leftovers once made every new one hang there).
STUCK = "#!/bin/sh\nexec sleep 1000\n"
STUCK_NODE = "  - node: {pkg: fleet_test, exec: stuck, name: stuck}\n"


def templates_with_stuck(cluster, source: Path, template: str, copy: Path) -> Path:
    """`source`'s templates copied to `copy`, with template `stuck_<template>`: `template` and
    one node more that never joins the graph (its executable installed in the cluster's prefix)."""
    stuck = cluster.prefix / "lib" / "fleet_test" / "stuck"
    stuck.write_text(STUCK)
    stuck.chmod(0o755)
    shutil.copytree(source, copy)
    launch = (copy / f"{template}.launch.yaml.j2").read_text()
    (copy / f"stuck_{template}.launch.yaml.j2").write_text(launch + STUCK_NODE)
    shutil.copy(copy / f"{template}.params.yaml", copy / f"stuck_{template}.params.yaml")
    return copy


def deploy_failing_on(cluster, spec: Path, robot: str, reason: str) -> dict[str, dict]:
    """Deploy `spec`, which fails on `robot` for `reason` (past the start-up grace); then the
    fleet's robots as `fleet status --json` shows them, by name."""
    done = cluster.cli("deploy", str(spec), "--timeout", "35", "--connect", cluster.endpoint, timeout=90)
    assert done.returncode == 1, done.stdout + done.stderr
    assert "fleet up" not in done.stdout
    assert f"not running: {robot} degraded ({reason})" in done.stdout, done.stdout
    status = json.loads(cluster.cli("status", "--json", "--connect", cluster.endpoint).stdout)
    return {row["name"]: row for row in status["robots"]}


def test_a_robot_runs_when_its_nodes_are_in_the_ros_graph(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    templates = templates_with_stuck(cluster, DATA / "templates", "tiny", tmp_path / "templates")
    robots = [
        {"name": "r1"},  # a ROS node: in the graph
        {"name": "r2", "template": "stuck_tiny"},  # the same, and one outside the graph
        {"name": "r3", "template": "idle"},  # a plain executable: never in the graph, judged by its process
    ]
    spec = cluster.spec(robots=robots, templates=str(templates), agents={"hostA": {}})
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.wait_agents_online("hostA")

    reason = "node /r2/stuck not in the ROS graph, though its process runs"
    robots_seen = deploy_failing_on(cluster, spec, "r2", reason)
    assert {name: (row["state"], row["reason"]) for name, row in robots_seen.items()} == {
        "r1": ("running", ""),
        "r2": ("degraded", reason),
        "r3": ("running", ""),
    }
    graph = {name: {n["name"]: (n["ros"], n["in_graph"]) for n in row["nodes"]} for name, row in robots_seen.items()}
    assert graph == {
        "r1": {"sleeper": (True, True)},
        "r2": {"sleeper": (True, True), "stuck": (True, False)},
        "r3": {"idle-1": (False, None)},
    }
    assert all(n["state"] == "running" for row in robots_seen.values() for n in row["nodes"])  # every process runs
    with cluster.client() as client:
        statuses, _ = client.status()
    assert {(s.agent.name, s.has_world) for s in statuses} == {("hostA", False)}

    shown = cluster.cli("status", "r2", "--connect", cluster.endpoint)
    assert shown.returncode == 1, shown.stdout + shown.stderr
    rows = {line.split()[1]: line.split()[-1] for line in shown.stdout.splitlines() if line.startswith("r2 ")}
    assert rows["sleeper"] == "yes" and rows["stuck"] == "no", shown.stdout

    # The stuck node gone from its launch file, the robot runs: its one node is in the graph.
    fixed = cluster.spec(
        robots=[{"name": "r1"}, {"name": "r2"}, {"name": "r3", "template": "idle"}],
        templates=str(templates),
        agents={"hostA": {}},
    )
    again = cluster.cli("deploy", str(fixed), "--timeout", "60", "--connect", cluster.endpoint, timeout=90)
    assert again.returncode == 0 and "fleet up" in again.stdout, again.stdout + again.stderr
    poll(
        lambda: json.loads(cluster.cli("status", "--json", "--connect", cluster.endpoint).stdout)["all_running"],
        timeout=5,
        what="every robot running",
    )


def test_in_a_world_a_robot_whose_data_flows_runs_only_with_all_its_nodes_in_the_graph(host_a, tmp_path):
    cluster = host_a
    templates = templates_with_stuck(cluster, REPO / "templates", "diff_drive", tmp_path / "templates")
    spec = cluster.two_robots_on_host_a("process")
    data = yaml.safe_load(spec.read_text())
    data["templates"] = str(templates)
    data["robots"][1]["template"] = "stuck_diff_drive"
    spec.write_text(yaml.safe_dump(data, sort_keys=False))
    try:
        reason = "node /robot2/stuck not in the ROS graph, though its process runs"
        robots = deploy_failing_on(cluster, spec, "robot2", reason)
        assert {name: (row["state"], row["reason"]) for name, row in robots.items()} == {
            "world": ("running", ""),
            "robot1": ("running", ""),
            "robot2": ("degraded", reason),
        }
        # Its data flows all the same: the world hears its controller, which gets the world's odom.
        moved = robots["robot2"]["velocity"]
        assert moved is not None and abs(moved["linear"]) > 0.01, robots["robot2"]
        seen = {n["name"]: n["in_graph"] for n in robots["robot2"]["nodes"]}
        assert seen == {"controller": True, "battery": True, "safety": True, "stuck": False}
        with cluster.client() as client:  # the agent says the fleet has a world, wherever it runs
            statuses, _ = client.status("two_robots")
        assert [(s.agent.name, s.has_world) for s in statuses] == [("hostA", True)]
    finally:
        cluster.cli("down", "two_robots", "--connect", cluster.endpoint, timeout=60)
