"""The pure parts of isolation: agent: placing robots in hosts, host requests, request checks."""

from __future__ import annotations

import json

import pytest

from fleet.nodes.host import RequestError, parse_request
from fleet.runtime.hosting import add_request, host_command, place
from fleet.runtime.isolation import plan_processes
from fleet.runtime.launch_file import load_launch_file
from fleet.runtime.node_log import is_launch_logger, launch_line, lines_of, logger_name, logger_of
from tests.runtime.test_command_line import _robot_plan


def test_place_fills_hosts_in_order_up_to_the_group_size():
    assert place([], 25) is None
    assert place([25, 3], 25) == 1
    assert place([2, 0], 2) == 1
    assert place([1, 0], 2) == 0
    assert place([1, 1, 1], 1) is None


def test_logger_names_follow_rcutils():
    assert logger_name("/robot1/controller") == "robot1.controller"
    assert logger_name("/site/a/r1/battery") == "site.a.r1.battery"
    assert logger_of("[ERROR] [1700000000.123456789] [robot1.controller]: boom") == "robot1.controller"
    assert logger_of("Traceback (most recent call last):") is None


def test_the_lines_of_one_node_of_a_shared_process():
    lines = [
        "starting",  # before any logger: whose, nobody can say
        "[INFO] [1.0] [r1.controller]: driving",
        "[INFO] [1.1] [r1.battery]: 80%",
        "[ERROR] [1.2] [r1.controller.planner]: boom",  # a child logger of the node
        "Traceback (most recent call last):",
        "[INFO] [1.3] [r1.controllers]: not the controller's",
    ]
    assert lines_of(lines, "r1.controller") == lines[1:2] + lines[3:5]
    assert lines_of(lines, "r1.battery") == [lines[2]]
    assert lines_of(["plain", "lines"], "r1.controller") is None  # a format without loggers


def test_the_lines_about_a_shared_process_are_every_one_of_its_nodes():
    lines = [
        launch_line("composite-1", "INFO", "process started with pid [10]"),
        "[INFO] [1.0] [r1.controller]: driving",
        "[INFO] [1.1] [r1.battery]: 80%",
        launch_line("composite-1", "ERROR", "process has died [pid 10, exit code -9, cmd: x]"),
        "left by no logger after the process line: nobody's",
    ]
    assert lines_of(lines, "r1.controller") == [lines[0], lines[1], lines[3]]
    assert lines_of(lines, "r1.battery") == [lines[0], lines[2], lines[3]]
    assert logger_of(lines[3]) == "composite-1" and is_launch_logger("composite-1")
    assert not is_launch_logger("r1.controller")


def test_agent_isolation_leaves_composable_nodes_to_the_host(prefix, tmp_path):
    prefix.add("talker", "#!/bin/sh\nexec sleep 100\n")
    extra = tmp_path / "more.launch.yaml"
    extra.write_text(
        "launch:\n"
        "- node: {pkg: demo, exec: talker, name: t}\n"
        "- node: {pkg: fleet_nodes, exec: controller, name: c1, namespace: r1}\n"
        "- node: {pkg: fleet_nodes, exec: safety, name: s1, namespace: r1, args: --plain}\n"
    )
    plan = load_launch_file(extra, env=prefix.env(), params_dir=tmp_path / "params")
    # The host takes the controller; the talker and the safety node with a plain argument run alone.
    assert [spec.name for spec in plan_processes(plan.nodes, "agent")] == [
        "talker-1",
        "safety-3",
    ]  # one counter (issue 11)


def test_add_request_carries_each_nodes_own_arguments(prefix, tmp_path):
    plan = _robot_plan(prefix, tmp_path)
    request = add_request("robot1", plan.nodes)
    assert request["op"] == "add" and request["robot"] == "robot1"
    assert [(n["executable"], n["ros_args"]) for n in request["nodes"]] == [
        (node.executable, node.cmd[1:]) for node in plan.nodes
    ]
    # the host says what it has to say of a node under the logger the agent files that node's lines by
    assert [n["logger"] for n in request["nodes"]] == [logger_name(node.fqn or node.executable) for node in plan.nodes]
    assert parse_request(json.dumps(request).encode()) == request  # the host accepts what we send
    assert host_command(tmp_path / "h.sock")[-2:] == ["--control", str(tmp_path / "h.sock")]


@pytest.mark.parametrize(
    "line, problem",
    [
        (b"{nope", "not JSON"),
        (b"[1, 2]", '"op"'),
        (b'{"op": "launch"}', "unknown op 'launch'"),
        (b'{"op": "remove"}', '"robot"'),
        (b'{"op": "add", "robot": "r1", "nodes": []}', "non-empty list"),
        (b'{"op": "add", "robot": "r1", "nodes": [{"executable": "rm", "ros_args": []}]}', "executable of"),
        (b'{"op": "add", "robot": "r1", "nodes": [{"executable": "battery", "ros_args": "-r"}]}', "list of strings"),
        (b'{"op": "add", "robot": "r1", "nodes": [{"executable": "battery", "ros_args": []}]}', '"logger"'),
        (b'{"op": "fault", "robot": "r1"}', '"node"'),
    ],
)
def test_bad_host_requests_are_refused(line, problem):
    with pytest.raises(RequestError) as refused:
        parse_request(line)
    assert problem in str(refused.value)
