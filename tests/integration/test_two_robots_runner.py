"""fleets/two_robots.yaml rendered and run by the embedded runner, checked from a separate
rclpy process view: namespaced nodes and topics, per-robot parameters, refused live changes,
respawn after SIGKILL, and nothing left behind."""

from __future__ import annotations

import math
import os
import signal

import psutil
import pytest

from fleet.runtime.supervisor import LaunchSession
from fleet.testing.ros import RosProbe
from tests.checkout import FLEETS, run_fleet

pytestmark = pytest.mark.integration

NODES = {f"/{robot}/{node}" for robot in ("robot1", "robot2") for node in ("controller", "battery", "safety")}


@pytest.fixture
def rendered(tmp_path):
    out = tmp_path / "out"
    assert run_fleet(["render", str(FLEETS / "two_robots.yaml"), "-o", str(out)]) == 0
    return out


@pytest.fixture
def probe(ros_env):
    with RosProbe() as probe:
        yield probe


def clear_scan():
    from sensor_msgs.msg import LaserScan

    return LaserScan(
        angle_min=-math.pi,
        angle_max=math.pi,
        angle_increment=2 * math.pi / 360,
        range_min=0.1,
        range_max=8.0,
        ranges=[math.inf] * 360,
    )


def test_two_robots_run_namespaced_with_their_own_parameters(rendered, ros_env, probe, tmp_path):
    from geometry_msgs.msg import Twist

    robot1 = LaunchSession(
        rendered / "robot1" / "robot1.launch.yaml",
        {},
        env=ros_env,
        log_dir=tmp_path / "logs1",
        isolation="process",
        backend="embedded",
    )
    robot2 = LaunchSession(
        rendered / "robot2" / "robot2.launch.yaml",
        {},
        env=ros_env,
        log_dir=tmp_path / "logs2",
        isolation="robot",
        backend="embedded",
    )
    with robot1, robot2:
        probe.wait_for_nodes(NODES, timeout=60)
        # Nodes are discovered before all their endpoints are (more so on a loaded machine).
        wanted = {
            f"/{robot}/{topic}"
            for robot in ("robot1", "robot2")
            for topic in ("cmd_vel", "cmd_vel_nav", "odom", "scan", "battery", "diagnostics")
        }

        def all_topics():
            seen = probe.topics()
            return seen if wanted <= set(seen) else None

        topics = probe.wait_until(all_topics, 30, f"the topics {sorted(wanted)}")
        assert "/cmd_vel" not in topics and "/odom" not in topics

        # Each node holds its own robot's effective parameters (fleet defaults 0.4, robot2's override 0.8).
        assert probe.get_parameters("/robot1/controller", ["max_speed", "use_sim_time"]) == [0.4, True]
        assert probe.get_parameters("/robot2/controller", ["max_speed"]) == [0.8]
        assert probe.get_parameters("/robot2/controller", ["waypoints"])[0] == [
            0.0,
            2.0,
            -1.0,
            2.0,
            -1.0,
            0.0,
            0.0,
            0.0,
        ]
        assert probe.get_parameters("/robot1/battery", ["capacity"]) == [50.0]

        # A live change outside the declared range is refused with a reason; a valid one is taken.
        accepted, reason = probe.set_parameter("/robot1/controller", "max_speed", 99.0)
        assert not accepted and reason
        assert probe.get_parameters("/robot1/controller", ["max_speed"]) == [0.4]
        assert probe.set_parameter("/robot1/controller", "max_speed", 0.6) == (True, "")

        # robot1's commands (relayed by its safety node) reach /robot1/cmd_vel and never robot2.
        seen1 = probe.subscribe("/robot1/cmd_vel", Twist)
        seen2 = probe.subscribe("/robot2/cmd_vel", Twist)
        command = Twist()
        command.linear.x = 0.37

        def forwarded() -> bool:
            probe.publish("/robot1/scan", clear_scan())
            probe.publish("/robot1/cmd_vel_nav", command)
            return any(abs(m.linear.x - 0.37) < 1e-6 for m in seen1.messages)

        probe.wait_until(forwarded, timeout=20, what="robot1's safety node to relay the command")
        probe.spin(0.5)
        assert not any(abs(m.linear.x - 0.37) < 1e-6 for m in seen2.messages)

        # SIGKILL a node: respawned, and its restart count says so.
        battery = next(s for s in robot1.status() if s.fqn == "/robot1/battery")
        assert battery.pid is not None
        os.kill(battery.pid, signal.SIGKILL)

        def respawned():
            now = next(s for s in robot1.status() if s.fqn == "/robot1/battery")
            return now if now.restarts == 1 and now.state == "running" and now.pid != battery.pid else None

        after = probe.wait_until(respawned, timeout=30, what="the battery node to be respawned")

        def serves_parameters() -> bool:
            try:  # discovery may still list the killed process's service for a moment
                return probe.get_parameters("/robot1/battery", ["capacity"], timeout=5) == [50.0]
            except AssertionError:
                return False

        probe.wait_until(serves_parameters, 40, "the respawned battery node to serve its parameters")
        pids = {s.pid for s in robot1.status() + robot2.status() if s.pid is not None}
    # Stopping the runner leaves no process behind, by pid and by process group.
    for pid in pids | {after.pid, battery.pid}:
        assert not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
    leftover = [p for p in psutil.process_iter(["pid"]) if _pgid(p.pid) in pids]
    assert not leftover


def _pgid(pid: int) -> int | None:
    try:
        return os.getpgid(pid)
    except (ProcessLookupError, PermissionError):
        return None
