"""`fleet status ROBOT...`: the view cut down to the robots named, and a table of their nodes."""

from __future__ import annotations

import pytest

from fleet.cli.output import console
from fleet.cli.status_view import print_view
from fleet.client.robots import robots_named
from fleet.errors import BadRequest
from fleet.plan.view import AgentRow, FleetView, RobotRow, WorldRow


def node(name: str, state: str = "running", pid: int | None = 100, restarts: int = 0, exit_code=None, uptime=75.0):
    return {"name": name, "state": state, "pid": pid, "restarts": restarts, "exit_code": exit_code, "uptime": uptime}


def two_fleets() -> FleetView:
    agents = [AgentRow(name, True, 0.0, fleets=["f"]) for name in ("rack_a", "rack_b", "rack_c")]
    robots = [
        RobotRow("f", "world", "world", "rack_a", "running", nodes=[node("world", pid=10)]),
        RobotRow(
            "f",
            "r1",
            "robot",
            "rack_a",
            "degraded",
            nodes=[node("controller", "backoff", pid=None, restarts=2, exit_code=2), node("battery", pid=11)],
        ),
        RobotRow("f", "r2", "robot", "rack_b", "running", nodes=[node("controller", pid=12)]),
        RobotRow("g", "r1", "robot", "rack_c", "running", nodes=[node("controller", pid=13)]),
    ]
    worlds = [WorldRow("f", "rack_a", 1.0, 1.0, 2, {"count": 0}, [])]
    return FleetView(agents=agents, robots=robots, domain_ids={"f": 1, "g": 2}, worlds=worlds)


def test_the_robots_named_their_agents_and_their_fleets_worlds_are_kept():
    view = two_fleets().of_robots(["r2"])
    assert [(row.fleet, row.name) for row in view.robots] == [("f", "r2")]
    assert [agent.name for agent in view.agents] == ["rack_b"]
    assert [world.fleet for world in view.worlds] == ["f"] and view.domain_ids == {"f": 1}
    assert view.all_running

    both = two_fleets().of_robots(["r1"])  # a name in two fleets: both
    assert [(row.fleet, row.agent) for row in both.robots] == [("f", "rack_a"), ("g", "rack_c")]
    assert not both.all_running  # exit 1: one of them is degraded


def test_a_robot_not_deployed_is_bad_input_naming_those_that_are():
    with pytest.raises(BadRequest, match=r"no robot named 'r9' is deployed \(robots: r1, r2, world\)"):
        robots_named(two_fleets(), ["r1", "r9"], None)
    with pytest.raises(BadRequest, match="no robot named 'r2' is deployed in fleet g"):
        robots_named(two_fleets(), ["r2"], "g")


def test_the_nodes_table_has_a_row_per_node(capsys):
    print_view(two_fleets().of_robots(["r1", "world"]), console(), nodes=True)
    lines = capsys.readouterr().out.splitlines()
    table = lines[lines.index("Nodes") + 1 :]
    assert table[0].split() == ["FLEET", "ROBOT", "NODE", "STATE", "PID", "RESTARTS", "UP", "LAST", "EXIT"]
    rows = [line.split() for line in table[2:6]]
    assert rows == [
        ["f", "world", "world", "running", "10", "0", "1", "min"],
        ["f", "r1", "controller", "backoff", "2", "2"],  # no process now; exited with code 2
        ["f", "r1", "battery", "running", "11", "0", "1", "min"],
        ["g", "r1", "controller", "running", "13", "0", "1", "min"],
    ]


def test_without_robots_named_there_is_no_nodes_table(capsys):
    print_view(two_fleets(), console())
    assert "Nodes" not in capsys.readouterr().out.splitlines()


def test_without_a_world_the_nodes_table_says_which_are_in_the_ros_graph(capsys):
    rows = [
        RobotRow("f", "r1", "robot", "rack_a", "degraded", nodes=[dict(node("a"), ros=True, in_graph=True)]),
        RobotRow("f", "r2", "robot", "rack_a", "degraded", nodes=[dict(node("b"), ros=True, in_graph=False)]),
        RobotRow("f", "r3", "robot", "rack_a", "running", nodes=[dict(node("c"), in_graph=None)]),  # not ROS
    ]
    print_view(FleetView(agents=[], robots=rows), console(), agents=False, nodes=True)
    lines = capsys.readouterr().out.splitlines()
    table = lines[lines.index("Nodes") + 1 :]
    assert table[0].split()[-3:] == ["IN", "ROS", "GRAPH"]
    assert [line.split()[-1] for line in table[2:5]] == ["yes", "no", "min"]  # r3's cell is blank


def test_robots_that_report_no_nodes_get_no_empty_nodes_table(capsys):
    offline = RobotRow("f", "r1", "robot", "rack_a", "offline", reason="agent rack_a does not answer")
    print_view(FleetView(agents=[], robots=[offline]), console(), agents=False, nodes=True)
    out = capsys.readouterr().out
    assert "agent rack_a does not answer" in out and "Nodes" not in out.splitlines()
    (line,) = [line for line in out.splitlines() if line.startswith("r1 ")]
    assert line.split()[:4] == ["r1", "rack_a", "offline", "-"]  # its nodes unknown, not 0 of 0
