"""isolation: agent at the runtime level: real fleet_nodes in real host processes, seen from rclpy."""

from __future__ import annotations

import json
import os
import signal
import socket

import pytest

from fleet.runtime.hosting import HostPool
from fleet.runtime.node_log import logger_of
from fleet.runtime.supervisor import LaunchSession
from fleet.testing.hosting import start_hosted_robot
from fleet.testing.poll import poll
from fleet.testing.ros import RosProbe

pytestmark = pytest.mark.integration

LAUNCH = """
launch:
- group:
  - push_ros_namespace: {{namespace: {robot}}}
  - node:
      pkg: fleet_nodes
      exec: controller
      name: controller
      respawn: 'true'
      respawn_delay: 0.2
      param:
      - {{from: $(dirname)/{robot}.params.yaml}}
      - {{name: goal_tolerance, value: {tolerance}}}
      remap:
      - {{from: cmd_vel, to: cmd_vel_nav}}
  - node:
      pkg: fleet_nodes
      exec: battery
      name: battery
      param:
      - {{from: $(dirname)/{robot}.params.yaml}}
"""
PARAMS = """
/{robot}/controller:
  ros__parameters:
    max_speed: {speed}
/{robot}/battery:
  ros__parameters:
    capacity: {capacity}
"""
ROBOTS = ("robot1", "robot2", "robot3")


@pytest.fixture
def probe(ros_env):
    with RosProbe() as probe:
        yield probe


def start_robot(tmp_path, ros_env, pool: HostPool, index: int) -> LaunchSession:
    robot = ROBOTS[index]
    params = PARAMS.format(robot=robot, speed=0.1 * (index + 1), capacity=40.0 + index)
    (tmp_path / f"{robot}.params.yaml").write_text(params)
    path = tmp_path / f"{robot}.launch.yaml"
    path.write_text(LAUNCH.format(robot=robot, tolerance=0.1 + 0.05 * index))
    return start_hosted_robot(path, pool, ros_env, tmp_path / robot / "logs")


def states(pool: HostPool) -> dict[str, tuple]:
    """robot -> (states, pids, restarts) of its nodes."""
    result = {}
    for robot in pool.robots():
        nodes = pool.node_status(robot)
        result[robot] = (
            {node.state for node in nodes},
            {node.pid for node in nodes},
            {node.restarts for node in nodes},
        )
    return result


def all_running(pool: HostPool) -> bool:
    return all(s == {"running"} for s, _, _ in states(pool).values())


def talk(control, lines: list[bytes]) -> list[dict]:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as connection:
        connection.connect(str(control))
        stream = connection.makefile("rwb")
        replies = []
        for line in lines:
            stream.write(line + b"\n")
            stream.flush()
            replies.append(json.loads(stream.readline()))
        return replies


def test_robots_share_hosts_and_a_fault_stays_with_its_robot(ros_env, probe, tmp_path):
    pool = HostPool(tmp_path / "hosts", ros_env, group_size=2)
    sessions = []
    try:
        sessions = [start_robot(tmp_path, ros_env, pool, index) for index in range(3)]
        # The launch sessions run nothing themselves: every node here is composable.
        assert all(session.status() == [] for session in sessions)
        probe.wait_for_nodes({f"/{r}/{n}" for r in ROBOTS for n in ("controller", "battery")})
        poll(lambda: all_running(pool), timeout=30, what="all hosted robots running")
        before = states(pool)
        # Two robots per host: robot1 and robot2 share one pid, robot3 has a host of its own.
        assert before["robot1"][1] == before["robot2"][1] != before["robot3"][1]
        assert len(pool.hosts) == 2
        # Each node has exactly its own parameters: file, then the inline value.
        for index, robot in enumerate(ROBOTS):
            got = probe.get_parameters(f"/{robot}/controller", ["max_speed", "goal_tolerance"])
            assert got == pytest.approx([0.1 * (index + 1), 0.1 + 0.05 * index])
            assert probe.get_parameters(f"/{robot}/battery", ["capacity"]) == [40.0 + index]
        assert "/robot2/cmd_vel_nav" in probe.topics()  # the remap is robot2's own

        host = pool.host_of("robot2")
        assert host is not None
        # A bad request gets an error reply; the host keeps running.
        bad = talk(host.control, [b"{not json", b'{"op": "explode"}', b'{"op": "remove", "robot": "nobody"}'])
        assert [reply["ok"] for reply in bad] == [False, False, False]
        assert "unknown op" in bad[1]["error"] and "nobody" in bad[2]["error"]

        # robot2's controller raises in a callback: robot2 alone restarts, in the same host.
        assert host.request({"op": "fault", "robot": "robot2", "node": "controller"}) == {"ok": True}
        poll(
            lambda: states(pool)["robot2"],
            until=lambda s: s[0] == {"running"} and s[2] == {1},
            timeout=30,
            what="robot2 restarted once",
        )
        after = states(pool)
        assert after["robot1"] == before["robot1"] and after["robot3"] == before["robot3"]
        assert after["robot2"][1] == before["robot2"][1]  # same host process
        log = pool.log_file("robot2", "controller")
        assert log is not None
        poll(lambda: log.read_text(), until=lambda text: "fault injected" in text, timeout=10, what="traceback in log")
        other = pool.log_file("robot1", "controller")
        assert other is not None
        assert "fault injected" not in other.read_text()
        assert "robot2.controller" not in other.read_text()

        # Removing robot1 leaves robot2 (same host) and robot3 alone.
        pool.remove_robot("robot1")
        probe.wait_until(lambda: "/robot1/controller" not in probe.node_names(), 20, "robot1's nodes gone")
        assert states(pool)["robot2"] == after["robot2"]
        assert states(pool)["robot3"] == after["robot3"]

        # A host that dies is started again with its robots, each counting a restart.
        host3 = pool.host_of("robot3")
        assert host3 is not None
        old_pid = next(iter(after["robot3"][1]))
        os.kill(old_pid, signal.SIGKILL)
        poll(
            lambda: states(pool)["robot3"],
            until=lambda s: s[0] == {"running"} and s[2] == {1} and s[1] != {old_pid},
            timeout=40,
            what="robot3 back in a new host",
        )
        assert states(pool)["robot2"] == after["robot2"]
        probe.wait_for_nodes({"/robot3/controller", "/robot2/controller"})
    finally:
        pool.stop()
        for session in sessions:
            session.stop()


def test_a_hosts_lines_about_a_robots_node_land_in_that_nodes_log(ros_env, tmp_path):
    """robot1's battery and robot2's controller cannot be made (a parameter out of range, waypoints
    of odd length): the host says so, at each try, under the node's logger, so each line is in
    the log of the node it is about.  It used to print them under no logger, and the agent filed
    them under whichever node had printed last: robot2's in robot1's controller log, robot1's
    battery's in robot1's controller log."""
    bad = {
        "robot1": "/robot1/battery:\n  ros__parameters:\n    capacity: -1.0\n",
        "robot2": "/robot2/controller:\n  ros__parameters:\n    waypoints: [1.0, 2.0, 3.0]\n",
    }
    pool = HostPool(tmp_path / "hosts", ros_env, group_size=2)
    sessions = []
    try:
        for robot, params in bad.items():
            (tmp_path / f"{robot}.params.yaml").write_text(params)
            path = tmp_path / f"{robot}.launch.yaml"
            path.write_text(LAUNCH.format(robot=robot, tolerance=0.1))
            sessions.append(start_hosted_robot(path, pool, ros_env, tmp_path / robot / "logs"))
        assert pool.host_of("robot1") is pool.host_of("robot2")

        def host_lines(robot: str, node: str) -> list[str]:
            log = pool.log_file(robot, node)
            assert log is not None
            return [line for line in log.read_text().splitlines() if "host: " in line]

        # Each robot is tried again after a backoff: its line comes once per try.
        poll(
            lambda: (host_lines("robot1", "battery"), host_lines("robot2", "controller")),
            until=lambda found: all(len(lines) >= 2 for lines in found),
            timeout=40,
            what="the host's lines about each failing node, twice, in that node's log",
        )
        for robot, node in (("robot1", "battery"), ("robot2", "controller")):
            for line in host_lines(robot, node):
                assert logger_of(line) == f"{robot}.{node}", line
                assert f"cannot create the nodes of robot {robot}: /{robot}/{node}: " in line, line
        assert host_lines("robot1", "controller") == []
        assert host_lines("robot2", "battery") == []
        for node in ("controller", "battery"):
            log = pool.log_file("robot1", node)
            assert log is not None and "robot2" not in log.read_text()
    finally:
        pool.stop()
        for session in sessions:
            session.stop()
