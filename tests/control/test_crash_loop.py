"""fleets/two_robots.yaml with robot2's controller refusing its waypoints at every start (a route
file on its agent's computer holds 3 values), over the control plane with real nodes and the
world: the deploy stops waiting for robot2 and fails, and status says it is `degraded` and why
(the node, its exit, its restarts, its own words), whichever isolation runs it.  A deploy that
does not wait is ok once taken, and exits 0."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
import yaml

from fleet.expand.templating import builtin_template_dirs
from fleet.testing.poll import poll
from tests.control.control_helpers import ROUTE_REFUSAL as REFUSAL
from tests.control.control_helpers import Cluster, with_refused_route

pytestmark = pytest.mark.integration


def with_refused_route_of_robot2(cluster: Cluster, isolation: str) -> Path:
    """cluster.two_robots_on_host_a(isolation), whose robots' controllers also read a route file
    of hostA's computer, with a route of 3 values for robot2 (control_helpers.with_refused_route)."""
    site = cluster.root / f"site-{isolation}"
    diff_drive = builtin_template_dirs()[0] / "diff_drive.launch.yaml.j2"
    data = yaml.safe_load(cluster.two_robots_on_host_a(isolation).read_text())
    data["templates"] = str(site)
    data["defaults"]["template"] = with_refused_route(diff_drive, site, "robot2")
    path = cluster.root / f"two_robots-refused-route-{isolation}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def rows(document: dict) -> dict[str, dict]:
    return {row["name"]: row for row in document["robots"]}


@pytest.mark.parametrize("isolation", ["process", "agent"])
def test_a_robot_whose_node_keeps_exiting_is_degraded_with_why_and_fails_the_deploy_early(host_a, isolation):
    cluster = host_a
    refused = [str(with_refused_route_of_robot2(cluster, isolation)), "--connect", cluster.endpoint]
    began = time.monotonic()
    done = cluster.cli("deploy", *refused, "--json", "--timeout", "150", timeout=200)
    took = time.monotonic() - began
    outcome = json.loads(done.stdout)
    assert done.returncode == 1 and outcome["ok"] is False, done.stdout + done.stderr
    assert not outcome["timed_out"] and took < 100, f"waited {took:.0f} s for a robot that cannot come up"
    robots = rows(outcome["status"])
    assert robots["robot1"]["state"] == "running", robots["robot1"]
    # Why it failed, at the top of the JSON as the table's "not up:" line says it.
    (stuck,) = outcome["not_running"]
    assert (stuck["name"], stuck["agent"], stuck["state"]) == ("robot2", "hostA", "degraded") and REFUSAL in stuck[
        "reason"
    ]
    robot2 = robots["robot2"]
    assert robot2["state"] == "degraded" and REFUSAL in robot2["reason"], robot2
    if isolation == "process":
        assert robot2["reason"].startswith("controller exited with code "), robot2["reason"]
    else:  # the host creates a robot's nodes together, and names the one that refused
        assert robot2["reason"].startswith("its hosted nodes stopped (restarted "), robot2["reason"]
        assert f"/robot2/controller: {REFUSAL}" in robot2["reason"]

    # `fleet status` and the deploy's table say it too.  Between two exits the controller runs for
    # a moment, and robot2 is then `degraded` for its data that does not flow.
    def status() -> dict:
        shown = cluster.cli("status", "--json", "--fleet", "two_robots", "--connect", cluster.endpoint)
        assert shown.returncode == 1, shown.stdout + shown.stderr
        return rows(json.loads(shown.stdout))["robot2"]

    robot2 = poll(status, until=lambda row: REFUSAL in row["reason"], timeout=60, what="status saying why")
    assert robot2["state"] == "degraded", robot2
    table = cluster.cli("deploy", *refused, "--timeout", "150", timeout=200)
    assert table.returncode == 1 and "REASON" in table.stdout and REFUSAL in table.stdout, table.stdout


def test_a_deploy_without_waiting_is_ok_once_taken_and_exits_0(host_a):
    cluster = host_a
    up = cluster.cli(
        "deploy",
        str(cluster.two_robots_on_host_a("process")),
        "--connect",
        cluster.endpoint,
        "--timeout",
        "150",
        timeout=200,
    )
    assert up.returncode == 0, up.stdout + up.stderr
    done = cluster.cli(
        "deploy",
        str(cluster.two_robots_on_host_a("process")),
        "--set",
        "robot2.controller.max_speed=0.45",
        "--no-wait",
        "--json",
        "--connect",
        cluster.endpoint,
    )
    outcome = json.loads(done.stdout)
    assert done.returncode == 0 and outcome["ok"] is True and outcome["recorded"], done.stdout + done.stderr
    assert outcome["agents"]["hostA"]["changes"]["restart"] == ["robot2"]
    # Being restarted, robot2 is not `stopped`: it runs its old nodes still, or waits for its new ones.
    robot2 = rows(outcome["status"])["robot2"]
    assert robot2["state"] != "stopped", robot2
    poll(
        lambda: rows(json.loads(cluster.cli("status", "--json", "--connect", cluster.endpoint).stdout))["robot2"],
        until=lambda row: row["state"] == "running",
        timeout=60,
        what="robot2 running its new description",
    )
