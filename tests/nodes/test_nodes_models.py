"""The pure decision logic of the nodes (fleet.nodes.models): no ROS involved."""

from __future__ import annotations

import math
import subprocess
import sys

import pytest

from fleet.nodes import NODES, load_node_class, models
from fleet.nodes.composite import UsageError, log_levels, parse_groups


def test_wrap_and_yaw():
    assert models.wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)
    assert models.wrap_angle(-3 * math.pi / 2) == pytest.approx(math.pi / 2)
    half = math.sqrt(0.5)
    assert models.yaw_from_quaternion(0, 0, half, half) == pytest.approx(math.pi / 2)


def test_steer_drives_straight_at_a_goal_ahead_limited_by_max_speed():
    speed, turn = models.steer(0, 0, 0, (5, 0), max_speed=0.5, max_turn_rate=1.5)
    assert speed == pytest.approx(0.5) and turn == pytest.approx(0.0)


@pytest.mark.parametrize("goal, sign", [((0, 2), 1), ((0, -2), -1)])
def test_steer_turns_towards_the_goal_within_max_turn_rate(goal, sign):
    speed, turn = models.steer(0, 0, 0, goal, max_speed=0.5, max_turn_rate=0.7)
    assert turn == pytest.approx(sign * 0.7)
    assert speed == pytest.approx(0.0, abs=1e-9)  # 90 degrees off: turn in place


def test_steer_slows_with_heading_error_and_never_drives_away():
    ahead, _ = models.steer(0, 0, 0, (2, 0), 1.0, 1.0)
    skew, _ = models.steer(0, 0, 0, (2, 2), 1.0, 1.0)
    behind, turn = models.steer(0, 0, 0, (-2, 0.01), 1.0, 1.0)
    assert ahead > skew > 0.0
    assert behind == 0.0 and abs(turn) == pytest.approx(1.0)


def test_steer_approach_speed_is_capped_near_the_goal():
    speed, _ = models.steer(0, 0, 0, (0.05, 0), max_speed=5.0, max_turn_rate=1.0)
    assert speed == pytest.approx(models.APPROACH_GAIN * 0.05)


def test_follower_advances_loops_and_finishes():
    route = [(1.0, 0.0), (1.0, 1.0)]
    follower = models.WaypointFollower(list(route), loop=True)
    assert follower.update(0, 0, 0.1) == pytest.approx(1.0)
    follower.update(1.0, 0.05, 0.1)
    assert follower.index == 1
    follower.update(1.0, 1.0, 0.1)
    assert (follower.index, follower.laps) == (0, 1)

    once = models.WaypointFollower(list(route), loop=False)
    once.update(1, 0, 0.1)
    once.update(1, 1, 0.1)
    assert once.finished and once.index == 1
    once.set_loop(True)
    assert not once.finished and once.index == 0


@pytest.mark.parametrize("max_speed, rate", [(0.5, 20.0), (5.0, 20.0), (0.2, 1.0)])
def test_steering_and_follower_complete_the_default_square(max_speed, rate):
    """A unicycle driven by the law visits every waypoint, even fast or at a slow control rate."""
    route = models.pairs([2.0, 0.0, 2.0, 2.0, 0.0, 2.0, 0.0, 0.0])
    follower = models.WaypointFollower(route, loop=False)
    x = y = yaw = 0.0
    dt = 1.0 / rate
    for _ in range(int(200 * rate)):  # 200 s of simulated time at most
        follower.update(x, y, tolerance=0.15)
        if follower.finished:
            break
        v, w = models.steer(x, y, yaw, follower.goal, max_speed, max_turn_rate=1.5)
        assert 0.0 <= v <= max_speed and abs(w) <= 1.5
        x, y, yaw = x + v * math.cos(yaw) * dt, y + v * math.sin(yaw) * dt, yaw + w * dt
    assert follower.finished and math.hypot(x, y) <= 0.15


def test_follower_with_all_waypoints_reached_does_not_spin():
    follower = models.WaypointFollower([(0.0, 0.0), (0.0, 0.0)], loop=True)
    follower.update(0, 0, 0.1)  # returns although every waypoint is always within tolerance


def test_battery_drains_with_time_and_faster_with_motion():
    battery = models.BatteryModel(capacity_wh=1.0, energy_wh=1.0, idle_draw_w=3.6, motion_draw_w_per_mps=7.2)
    battery.advance(100.0)  # 3.6 W * 100 s = 0.1 Wh
    assert battery.fraction == pytest.approx(0.9)
    battery.speed = 0.5  # 3.6 W more
    battery.advance(100.0)
    assert battery.fraction == pytest.approx(0.7)
    battery.advance(-50.0)  # a clock going backwards drains nothing
    assert battery.fraction == pytest.approx(0.7)
    battery.advance(1e6)
    assert battery.fraction == 0.0


def test_battery_health_levels():
    assert models.battery_health(0.5, low=0.2, critical=0.05) == "good"
    assert models.battery_health(0.1, low=0.2, critical=0.05) == "low"
    assert models.battery_health(0.01, low=0.2, critical=0.05) == "dead"


def _ranges(obstacle_angle: float, distance: float, beams: int = 360) -> list[float]:
    ranges = [math.inf] * beams
    ranges[round((obstacle_angle + math.pi) / (2 * math.pi / beams)) % beams] = distance
    return ranges


def test_nearest_in_cone_sees_only_the_front():
    inc = 2 * math.pi / 360
    front = _ranges(0.1, 0.3)
    behind = _ranges(math.pi - 0.05, 0.3)
    assert models.nearest_in_cone(front, -math.pi, inc, 0.1, 8.0, 0.6) == pytest.approx(0.3)
    assert models.nearest_in_cone(behind, -math.pi, inc, 0.1, 8.0, 0.6) == math.inf
    # Returns below range_min are noise, not obstacles.
    assert models.nearest_in_cone(_ranges(0.0, 0.05), -math.pi, inc, 0.1, 8.0, 0.6) == math.inf
    # A scan laid out 0..2pi puts "ahead" at its start and end.
    assert models.nearest_in_cone([0.3] + [math.inf] * 359, 0.0, inc, 0.1, 8.0, 0.6) == pytest.approx(0.3)


def test_gate_forward_blocks_only_forward_motion():
    assert models.gate_forward(0.4, nearest_ahead=0.2, safety_distance=0.4) == 0.0
    assert models.gate_forward(-0.3, nearest_ahead=0.2, safety_distance=0.4) == -0.3
    assert models.gate_forward(0.4, nearest_ahead=1.0, safety_distance=0.4) == 0.4


def test_importing_the_package_does_not_load_rclpy():
    code = "import sys, fleet.nodes, fleet.nodes.models; sys.exit('rclpy' in sys.modules)"
    assert subprocess.run([sys.executable, "-c", code], timeout=30).returncode == 0


def test_registry_is_lazy_and_complete():
    assert set(NODES) == {"controller", "battery", "safety"}
    assert load_node_class("safety").__name__ == "SafetyNode"
    with pytest.raises(KeyError, match="known"):
        load_node_class("nope")


def test_composite_argument_groups():
    argv = [
        "--fleet-node",
        "controller",
        "--ros-args",
        "-r",
        "__ns:=/r1",
        "--fleet-node",
        "battery",
        "--ros-args",
        "--log-level",
        "debug",
        "--log-level",
        "rcl:=warn",
    ]
    groups = parse_groups(argv)
    assert groups == [("controller", argv[2:5]), ("battery", argv[7:])]
    assert log_levels(groups[1][1]) == [(None, "debug"), ("rcl", "warn")]
    for bad in ([], ["controller"], ["--fleet-node"], ["--fleet-node", "world", "--ros-args"]):
        with pytest.raises(UsageError):
            parse_groups(bad)


def test_nearest_in_cone_takes_minus_inf_as_too_close():
    """REP-117: -inf is a return closer than range_min, not a missing one."""
    ranges = [math.inf] * 360
    ranges[180] = -math.inf  # straight ahead for a scan starting at -pi
    assert models.nearest_in_cone(ranges, -math.pi, 2 * math.pi / 360, 0.1, 8.0, 0.6) == pytest.approx(0.1)
