"""The nodes as real rclpy nodes, hosted in the test's own context and driven over real topics.

One process keeps these fast; tests/nodes/test_nodes_processes.py covers the executables.
"""

from __future__ import annotations

import itertools
import math

import pytest

pytestmark = pytest.mark.integration

rclpy = pytest.importorskip("rclpy")

from builtin_interfaces.msg import Time  # noqa: E402
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus  # noqa: E402
from geometry_msgs.msg import PointStamped, Twist  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSDurabilityPolicy, QoSProfile  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import BatteryState, LaserScan  # noqa: E402

from fleet.nodes.battery import BatteryNode  # noqa: E402
from fleet.nodes.controller import ControllerNode  # noqa: E402
from fleet.nodes.models import yaw_from_quaternion  # noqa: E402
from fleet.nodes.safety import SafetyNode  # noqa: E402


def odom(x: float, y: float, yaw: float, speed: float = 0.0) -> Odometry:
    msg = Odometry()
    msg.header.frame_id = "odom"
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
    msg.twist.twist.linear.x = speed
    return msg


def twist(linear: float, angular: float) -> Twist:
    msg = Twist()
    msg.linear.x, msg.angular.z = linear, angular
    return msg


_scan_count = itertools.count(1)


def scan(obstacle_angle: float | None = None, distance: float = 0.2, beams: int = 360) -> LaserScan:
    msg = LaserScan()
    msg.header.stamp.sec = next(_scan_count)  # tells scans apart (their floats are float32)
    msg.angle_min, msg.angle_increment = -math.pi, 2 * math.pi / beams
    msg.angle_max = msg.angle_min + msg.angle_increment * (beams - 1)
    msg.range_min, msg.range_max = 0.1, 8.0
    ranges = [5.0] * beams
    if obstacle_angle is not None:
        i = round((obstacle_angle - msg.angle_min) / msg.angle_increment) % beams
        ranges[i] = distance
    msg.ranges = ranges
    return msg


def battery(health: int) -> BatteryState:
    return BatteryState(percentage=0.5, power_supply_health=health)


def diagnostics_of(ros, node_name: str) -> dict:
    """The key/values of the next diagnostics of node_name, with level and message."""
    seen = ros.latest(DiagnosticArray, "diagnostics")
    array = ros.spin_until(lambda: seen and seen[-1], timeout=3.0)
    status = next(s for s in array.status if s.name.endswith(node_name))
    return {
        "level": status.level,
        "message": status.message,
        **{kv.key: kv.value for kv in status.values},
    }


def test_controller_drives_towards_the_waypoint_and_stops_on_dead_battery(ros):
    node = ros.add(
        ControllerNode,
        "-p",
        "waypoints:=[2.0, 0.0, 2.0, 2.0]",
        "-p",
        "max_speed:=0.3",
        "-p",
        "max_turn_rate:=0.8",
        "-p",
        "control_rate:=50.0",
    )
    odom_pub = ros.probe.create_publisher(Odometry, "odom", 10)
    battery_pub = ros.probe.create_publisher(BatteryState, "battery", 10)
    cmds = ros.latest(Twist, "cmd_vel")
    goals = ros.latest(
        PointStamped,
        "controller/goal",
        QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL),
    )

    def command_after(msg):
        """The first command computed after msg arrived (commands are sent at control_rate)."""
        odom_pub.publish(msg)
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        pose = pytest.approx((p.x, p.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)))
        ros.spin_until(lambda: node.pose == pose)
        ros.spin_for(0.05)  # the controller's timer may have been due before the odometry
        del cmds[:]
        return ros.spin_until(lambda: cmds and cmds[-1])

    # Facing the goal: full allowed speed, no turn.
    cmd = command_after(odom(0.0, 0.0, 0.0))
    assert cmd.linear.x == pytest.approx(0.3) and cmd.angular.z == pytest.approx(0.0, abs=1e-6)
    # Facing +y with the goal along +x: turn right (negative) in place, at most max_turn_rate.
    cmd = command_after(odom(0.0, 0.0, math.pi / 2))
    assert cmd.angular.z == pytest.approx(-0.8) and cmd.linear.x == pytest.approx(0.0, abs=1e-6)
    # Slightly off to the left of the heading: drive and turn left, still within max_speed.
    cmd = command_after(odom(0.0, -0.5, 0.0))
    assert 0.0 < cmd.linear.x <= 0.3 and cmd.angular.z > 0.0

    # A live change of max_speed applies to the next command.
    result = node.set_parameters([Parameter("max_speed", value=0.1)])[0]
    assert result.successful
    assert command_after(odom(0.0, 0.0, 0.0)).linear.x == pytest.approx(0.1)

    # Reaching the first waypoint makes the second the goal (published on ~/goal).
    command_after(odom(1.95, 0.0, 0.0))
    ros.spin_until(lambda: goals and goals[-1].point.y == pytest.approx(2.0))
    diag = diagnostics_of(ros, "controller")
    assert diag["waypoint_index"] == "1" and diag["message"] == "driving"

    # A DEAD battery stops the robot; a GOOD one lets it go again.
    battery_pub.publish(battery(BatteryState.POWER_SUPPLY_HEALTH_DEAD))
    ros.spin_until(lambda: node.battery_dead)
    cmd = command_after(odom(2.0, 0.0, math.pi / 2))
    assert (cmd.linear.x, cmd.angular.z) == (0.0, 0.0)
    assert diagnostics_of(ros, "controller")["level"] == DiagnosticStatus.ERROR
    battery_pub.publish(battery(BatteryState.POWER_SUPPLY_HEALTH_GOOD))
    ros.spin_until(lambda: not node.battery_dead)
    assert command_after(odom(2.0, 0.0, math.pi / 2)).linear.x == pytest.approx(0.1)


def test_controller_refuses_bad_live_parameters_with_a_reason(ros):
    node = ros.add(ControllerNode)
    odd = node.set_parameters([Parameter("waypoints", value=[1.0, 2.0, 3.0])])[0]
    assert not odd.successful and "even length" in odd.reason
    fast = node.set_parameters([Parameter("max_speed", value=6.0)])[0]
    assert not fast.successful and "out of range" in fast.reason
    # An integer for a double parameter is taken as the number it is.
    assert node.set_parameters([Parameter("max_speed", value=1)])[0].successful
    assert node.params["max_speed"] == 1.0 and isinstance(node.params["max_speed"], float)


def test_battery_drains_with_sim_time_faster_with_motion_and_dies_below_critical(ros):
    # 1 Wh at 3.6 W idle lasts 1000 s; motion at 0.5 m/s adds another 3.6 W.
    node = ros.add(
        BatteryNode,
        "-p",
        "use_sim_time:=true",
        "-p",
        "capacity:=1.0",
        "-p",
        "idle_draw:=3.6",
        "-p",
        "motion_draw:=7.2",
        "-p",
        "publish_rate:=10.0",
        "-p",
        "low_threshold:=0.8",
        "-p",
        "critical_threshold:=0.6",
    )
    clock_pub = ros.probe.create_publisher(Clock, "/clock", 10)
    odom_pub = ros.probe.create_publisher(Odometry, "odom", 10)
    states = ros.latest(BatteryState, "battery")

    def at(sim_seconds: int) -> BatteryState:
        """The battery state published at sim time sim_seconds."""

        def stamped():
            clock_pub.publish(Clock(clock=Time(sec=sim_seconds)))
            return next((s for s in reversed(states) if s.header.stamp.sec == sim_seconds), None)

        return ros.spin_until(stamped)

    assert at(1000).percentage == pytest.approx(1.0)
    state = at(1100)
    assert state.percentage == pytest.approx(0.9, abs=1e-3)
    assert state.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD
    odom_pub.publish(odom(0.0, 0.0, 0.0, speed=0.5))
    ros.spin_until(lambda: node.model.speed == 0.5)
    state = at(1200)
    assert state.percentage == pytest.approx(0.7, abs=1e-3)  # twice the idle drain
    assert state.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD
    assert diagnostics_of(ros, "battery")["level"] == DiagnosticStatus.WARN  # below low
    state = at(1300)
    assert state.percentage == pytest.approx(0.5, abs=1e-3)
    assert state.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_DEAD
    assert diagnostics_of(ros, "battery")["level"] == DiagnosticStatus.ERROR

    refused = node.set_parameters([Parameter("critical_threshold", value=0.9)])[0]
    assert not refused.successful and "low_threshold" in refused.reason


def test_safety_passes_blocks_forward_ignores_behind_and_zeroes_on_scan_timeout(ros):
    node = ros.add(SafetyNode, "-p", "scan_timeout:=0.4", "-p", "safety_distance:=0.4")
    scan_pub = ros.probe.create_publisher(LaserScan, "scan", 10)
    cmd_pub = ros.probe.create_publisher(Twist, "cmd_vel_in", 10)
    outs = ros.latest(Twist, "cmd_vel_out")

    def gated(scan_msg: LaserScan, cmd: Twist) -> Twist:
        scan_pub.publish(scan_msg)
        ros.spin_until(lambda: node.last_scan and node.last_scan.header.stamp == scan_msg.header.stamp)
        ros.spin_for(0.02)  # let a re-sent command from the new verdict arrive before clearing
        del outs[:]
        cmd_pub.publish(cmd)
        return ros.spin_until(lambda: outs and outs[-1])

    # No scan yet: nothing moves.
    del outs[:]
    cmd_pub.publish(twist(0.3, 0.2))
    assert ros.spin_until(lambda: outs and outs[-1]) == Twist()

    assert gated(scan(), twist(0.3, 0.2)) == twist(0.3, 0.2)
    # Obstacle ahead (slightly off centre, inside the cone): forward blocked, turning still allowed.
    assert gated(scan(0.3, 0.2), twist(0.3, 0.2)) == twist(0.0, 0.2)
    assert gated(scan(0.3, 0.2), twist(-0.2, 0.0)) == twist(-0.2, 0.0)  # reversing away is fine
    # The same obstacle behind, or beside outside the cone, does not matter.
    assert gated(scan(math.pi, 0.2), twist(0.3, 0.0)) == twist(0.3, 0.0)
    assert gated(scan(1.2, 0.2), twist(0.3, 0.0)) == twist(0.3, 0.0)

    # An obstacle appearing acts at once on the last command, without waiting for a new one.
    del outs[:]
    scan_pub.publish(scan(0.0, 0.3))
    assert ros.spin_until(lambda: outs and outs[-1]) == twist(0.0, 0.0)

    # Scans stop: after scan_timeout a zero twist is sent even with no new command.
    assert gated(scan(), twist(0.3, 0.0)) == twist(0.3, 0.0)
    del outs[:]
    ros.spin_until(lambda: outs and outs[-1] == Twist(), timeout=2.0)
    cmd_pub.publish(twist(0.3, 0.0))
    ros.spin_until(lambda: len(outs) >= 2)
    assert outs[-1] == Twist()
    diag = diagnostics_of(ros, "safety")
    assert diag["level"] == DiagnosticStatus.ERROR and diag["message"] == "no recent scan"


def test_composite_applies_a_groups_log_level_to_its_node_only(ros):
    from fleet.nodes.composite import _create

    quiet = _create("battery", ["--ros-args", "-r", "__ns:=/r1", "--log-level", "error"], context=ros.context)
    plain = _create("safety", ["--ros-args", "-r", "__ns:=/r1"], context=ros.context)
    ros.nodes += [quiet, plain]
    assert quiet.get_fully_qualified_name() == "/r1/battery"
    assert quiet.get_logger().get_effective_level() == rclpy.logging.LoggingSeverity.ERROR
    assert plain.get_logger().get_effective_level() != rclpy.logging.LoggingSeverity.ERROR
