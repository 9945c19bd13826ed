"""`fleet param get/set/list` through the agent to a real rclpy node's parameter services."""

from __future__ import annotations

import json
import signal

import pytest
import yaml

from fleet.testing.poll import poll
from tests.control.control_helpers import robot

pytestmark = pytest.mark.integration


def param(cluster, *args):
    return cluster.cli("param", *args, "--connect", cluster.endpoint)


def test_set_is_checked_by_the_node_recorded_and_kept_across_an_agent_restart(fresh_cluster):
    cluster = fresh_cluster
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.wait_agents_online("hostA")
    spec = cluster.spec(defaults={"template": "one_controller", "agent": "hostA"}, robots=[{"name": "robot1"}])
    outcome = cluster.deploy(spec, timeout=60)
    assert outcome.ok, outcome.view and outcome.view.robots

    got = param(cluster, "get", "robot1", "controller", "max_speed")
    assert got.returncode == 0, got.stdout + got.stderr
    assert json.loads(got.stdout) == 0.5

    refused = param(cluster, "set", "robot1", "controller", "max_speed", "99")
    assert refused.returncode == 2 and "refused" in refused.stderr, refused.stdout + refused.stderr  # bad input
    # A negative value is the value (as with `ros2 param set`), not an unknown option: the node judges it.
    negative = param(cluster, "set", "robot1", "controller", "max_speed", "-0.5")
    assert negative.returncode == 2, negative.stdout + negative.stderr
    assert "refused max_speed=-0.5" in negative.stderr and "out of range" in negative.stderr, negative.stderr
    # Typed as --set types it (as rcl reads a parameter file): 1e-1 is a double, not a string.
    exponent = param(cluster, "set", "robot1", "controller", "max_speed", "1e-1")
    assert exponent.returncode == 0 and exponent.stdout.startswith("robot1/controller: max_speed = 0.1 "), exponent
    # Nothing at all is an empty string, as with `ros2 param set`: the node refuses it for a double.
    empty = param(cluster, "set", "robot1", "controller", "max_speed", "")
    assert empty.returncode == 2 and "refused max_speed='': " in empty.stderr, empty.stderr
    # Values are shown as ROS YAML writes them.
    assert param(cluster, "get", "robot1", "controller", "loop").stdout == "true\n"
    accepted = param(cluster, "set", "robot1", "controller", "max_speed", "1")  # an int for a double: coerced
    assert accepted.returncode == 0, accepted.stdout + accepted.stderr
    assert json.loads(param(cluster, "get", "robot1", "controller", "max_speed").stdout) == 1.0

    # A parameter the launch file gives inline after the parameter file (one_controller's
    # use_sim_time) is set live, but a restart would bring the launch file's value back: said, and
    # not recorded as kept.
    inline = param(cluster, "set", "robot1", "controller", "use_sim_time", "true")
    assert inline.returncode == 0, inline.stdout + inline.stderr
    assert inline.stdout == (
        "robot1/controller: use_sim_time = true (set live only: the launch file gives use_sim_time inline after "
        "the parameter file (robot1.launch.yaml:12:9: false), so a restart brings that value back)\n"
    ), inline.stdout
    assert param(cluster, "set", "robot1", "controller", "use_sim_time", "false").returncode == 0

    # Every parameter as the node holds it now, and which ones were set live.
    listed = param(cluster, "list", "robot1", "--json")
    assert listed.returncode == 0, listed.stdout + listed.stderr
    data = json.loads(listed.stdout)
    assert data["parameters"]["controller"]["max_speed"] == 1.0
    assert data["parameters"]["controller"]["use_sim_time"] is False
    assert data["set_live"] == {"controller": ["max_speed"]}
    table = param(cluster, "list", "robot1", "controller")
    row = next(line.split() for line in table.stdout.splitlines() if line.split()[1:2] == ["max_speed"])
    assert table.returncode == 0 and row == ["controller", "max_speed", "1.0", "yes"], table.stdout
    assert table.stdout.splitlines()[1].split() == ["NODE", "PARAMETER", "VALUE", "SET", "LIVE"], table.stdout
    # A node or robot the fleet does not have is the user's mistake: bad input, exit 2, one line.
    for args in (["list", "robot1", "no_such_node"], ["get", "robot1", "no_such_node", "max_speed"]):
        no_node = param(cluster, *args)
        assert no_node.returncode == 2, no_node.stderr
        assert no_node.stderr == (
            "fleet: error: <command line>: robot robot1 has no node 'no_such_node' (nodes: controller)\n"
        )
    no_node = cluster.cli("logs", "robot1", "no_such_node", "--connect", cluster.endpoint)
    assert no_node.returncode == 2 and "has no node 'no_such_node' (nodes: " in no_node.stderr, no_node.stderr
    no_robot = param(cluster, "get", "robot9", "controller", "max_speed")
    assert no_robot.returncode == 2 and "no robot named 'robot9' is deployed" in no_robot.stderr, no_robot.stderr

    desired = json.loads((cluster.state_dir("hostA") / "desired" / "tiny.json").read_text())
    assert desired["overrides"]["robot1"]["/robot1/controller"]["max_speed"] == 1.0
    params_file = cluster.state_dir("hostA") / "units" / "tiny" / "robot1" / "robot1.params.yaml"
    assert yaml.safe_load(params_file.read_text())["/robot1/controller"]["ros__parameters"]["max_speed"] == 1.0
    assert robot(cluster.view("tiny"), "robot1").overrides

    # So is a parameter the node does not have, to get or to set; a near miss is named.
    for args in (["get"], ["set", "0.5"]):
        unknown = param(cluster, args[0], "robot1", "controller", "no_such_parameter", *args[1:])
        assert unknown.returncode == 2, unknown.stdout + unknown.stderr
        assert unknown.stderr == (
            "fleet: error: <command line>: node /robot1/controller has no parameter 'no_such_parameter'\n"
        ), unknown.stderr
    # A long value reaches the node whole and is judged by it: one whose JSON passes the 128 KiB an
    # argument may hold (a URDF full of quotes, here 60 kB of text that JSON escapes to 180 kB).
    long_value = "\u00e9" * 30_000
    judged = param(cluster, "set", "robot1", "controller", "max_speed", long_value)
    assert judged.returncode == 2, judged.stdout + judged.stderr
    assert "it holds a double, and the value given is a string" in judged.stderr, judged.stderr
    typo = param(cluster, "get", "robot1", "controller", "max_sped")
    assert typo.returncode == 2 and typo.stderr == (
        "fleet: error: <command line>: node /robot1/controller has no parameter 'max_sped' "
        "(did you mean 'max_speed'?)\n"
    ), typo.stderr
    malformed = param(cluster, "get", "robot1", "controller", "max speed")
    assert malformed.returncode == 2 and malformed.stderr.count("\n") == 1, malformed.stderr
    assert malformed.stderr.startswith("fleet: error: <command line>: invalid parameter request: name: ")

    cluster.kill("agent-hostA", signal.SIGKILL)
    cluster.start_agent("hostA")
    poll(
        lambda: robot(cluster.view("tiny"), "robot1").state,
        until=lambda state: state == "running",
        timeout=30,
        what="robot1 restored by its agent",
    )
    poll(
        lambda: param(cluster, "get", "robot1", "controller", "max_speed").stdout.strip(),
        until=lambda value: value == "1.0",
        timeout=30,
        what="robot1's max_speed to read 1.0 after the restart",
    )

    # A deploy warns as render does (on stderr: --json keeps stdout one document) of a parameter
    # name the template's defaults do not have.
    typo = cluster.cli(
        "deploy", str(spec), "--set", "robot1.controller.max_sped=0.4", "--json", "--connect", cluster.endpoint
    )
    assert typo.returncode == 0, typo.stdout + typo.stderr
    assert json.loads(typo.stdout)["ok"] is True
    assert (
        "warning: --set robot1.controller.max_sped=0.4: controller.max_sped is not a parameter of the template's "
        "controller defaults (did you mean 'max_speed'?)" in typo.stderr
    ), typo.stderr
