"""ROS side of the world: one rclpy node, per-robot publishers and subscriptions, /clock.

Threading (stepSimulation holds the GIL, so the physics thread must stay busy with physics):
the executor spins in a background thread and its callbacks only store the latest command or
battery reading; the physics thread reads those and publishes odom/scan/clock itself, reusing one
message object per robot and topic so publishing costs little more than serialization.
"""

from __future__ import annotations

import array
import contextlib
import math
import threading
import time
from dataclasses import dataclass

import numpy as np
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState, LaserScan
from visualization_msgs.msg import MarkerArray

from fleet.world import markers
from fleet.world.description import ModelSpec, ObstacleSpec, RobotSpec

# Best-effort subscriptions match both reliable and best-effort publishers; reliable publishers
# match both kinds of subscribers (RViz, Nav2's sensor-data QoS, ros2 topic echo).
_SUB_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
_PUB_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def stamp(sim_time: float) -> Time:
    sec = math.floor(sim_time)
    return Time(sec=sec, nanosec=min(round((sim_time - sec) * 1e9), 999_999_999))


@dataclass
class Command:
    linear: float = 0.0
    angular: float = 0.0
    wall: float = -math.inf  # time.monotonic() when received
    sim: float = -math.inf  # sim time when received


class RobotChannel:
    """Everything ROS about one robot: its publishers, subscriptions and the latest inputs."""

    def __init__(self, node: Node, spec: RobotSpec, clock_source) -> None:
        self.spec = spec
        self.node = node
        ns = spec.namespace.rstrip("/")
        self.command = Command()
        self.battery: float | None = None
        self._sim_now = clock_source
        self.odom_pub = node.create_publisher(Odometry, f"{ns}/odom", _PUB_QOS)
        self.scan_pub = node.create_publisher(LaserScan, f"{ns}/scan", _PUB_QOS)
        self.truth_pub = (
            node.create_publisher(PoseStamped, f"{ns}/ground_truth", _PUB_QOS) if spec.ground_truth else None
        )
        self.cmd_sub = node.create_subscription(Twist, f"{ns}/cmd_vel", self._on_cmd, _SUB_QOS)
        self.battery_sub = node.create_subscription(BatteryState, f"{ns}/battery", self._on_battery, _SUB_QOS)
        self.markers_pub = node.create_publisher(MarkerArray, f"{ns}/markers", _PUB_QOS)

        self.odom = Odometry()
        self.odom.header.frame_id = f"{spec.name}/odom"
        self.odom.child_frame_id = f"{spec.name}/base_link"
        self.scan = LaserScan()
        lidar = spec.lidar
        self.scan.header.frame_id = f"{spec.name}/base_scan"
        self.scan.angle_min = lidar.angle_min
        self.scan.angle_increment = lidar.increment
        self.scan.angle_max = lidar.angle_min + lidar.increment * (lidar.beams - 1)
        self.scan.time_increment = 0.0  # all beams are taken at the same instant
        self.scan.scan_time = 1.0 / lidar.rate
        self.scan.range_min = lidar.range_min
        self.scan.range_max = lidar.range_max
        self.truth = PoseStamped()
        self.truth.header.frame_id = "world"
        # odom's origin is the robot's nominal spawn pose from world.yaml (not where a restarted
        # world put it back), so odom stays continuous when the world restarts.
        origin = spec.pose
        self._origin = (origin.x, origin.y, origin.yaw, math.cos(origin.yaw), math.sin(origin.yaw))

    # executor thread: store and return
    def _on_cmd(self, msg: Twist) -> None:
        self.command = Command(msg.linear.x, msg.angular.z, time.monotonic(), self._sim_now())

    def _on_battery(self, msg: BatteryState) -> None:
        self.battery = None if math.isnan(msg.percentage) else float(msg.percentage)

    # physics thread
    def current_command(self, sim_time: float) -> tuple[float, float]:
        """The latest command, or zero once it is older than cmd_timeout in both sim and wall time
        (a sim-time-only timeout would stop a wall-clock publisher in a faster-than-real-time
        world; a wall-only one would let a stalled controller drive on in a slow world)."""
        cmd = self.command
        timeout = self.spec.cmd_timeout
        if sim_time - cmd.sim > timeout and time.monotonic() - cmd.wall > timeout:
            return 0.0, 0.0
        return cmd.linear, cmd.angular

    def link(self) -> dict[str, float | int | None]:
        """What says this robot's data flows: the age of its last command (wall seconds, None:
        never received) and the subscriptions matched to its odom (its nodes, once discovered)."""
        wall = self.command.wall
        return {
            # max(): a command stamped in the future (a benchmark's "never expires") is fresh
            "cmd_age": None if wall == -math.inf else round(max(0.0, time.monotonic() - wall), 2),
            "odom_subscribers": self.odom_pub.get_subscription_count(),
        }

    def publish_odom(self, t: Time, x: float, y: float, yaw: float, vx: float, vy: float, wz: float) -> None:
        ox, oy, oyaw, c, s = self._origin
        dx, dy = x - ox, y - oy
        lx, ly, lyaw = c * dx + s * dy, -s * dx + c * dy, yaw - oyaw
        msg = self.odom
        msg.header.stamp = t
        pose = msg.pose.pose
        pose.position.x, pose.position.y = lx, ly
        pose.orientation.z, pose.orientation.w = math.sin(lyaw / 2), math.cos(lyaw / 2)
        twist = msg.twist.twist
        twist.linear.x, twist.linear.y, twist.angular.z = vx, vy, wz
        self.odom_pub.publish(msg)
        if self.truth_pub is not None:
            truth = self.truth
            truth.header.stamp = t
            truth.pose.position.x, truth.pose.position.y = x, y
            truth.pose.orientation.z, truth.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            self.truth_pub.publish(truth)

    def publish_scan(self, t: Time, ranges: np.ndarray) -> None:
        msg = self.scan
        msg.header.stamp = t
        # array('f') is the fast path of rclpy's float32[] setter (no per-element checks)
        msg.ranges = array.array("f", ranges.astype(np.float32).tobytes())
        self.scan_pub.publish(msg)

    def destroy(self) -> None:
        for entity in (self.odom_pub, self.scan_pub, self.truth_pub, self.markers_pub):
            if entity is not None:
                self.node.destroy_publisher(entity)
        self.node.destroy_subscription(self.cmd_sub)
        self.node.destroy_subscription(self.battery_sub)


class RosBridge:
    def __init__(self, ros_args: list[str] | None = None, node_name: str = "world") -> None:
        self.context = rclpy.Context()
        # The world handles SIGINT/SIGTERM itself (stop the loop, write a last status, clean up).
        rclpy.init(args=ros_args, context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = Node(node_name, context=self.context)
        self.clock_pub = self.node.create_publisher(Clock, "/clock", _PUB_QOS)
        self.scene_pub = self.node.create_publisher(MarkerArray, "~/markers", _PUB_QOS)
        self._clock_msg = Clock()
        self.channels: dict[str, RobotChannel] = {}
        self.sim_time = 0.0  # written by the physics thread, read by callbacks for stamps
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name="ros-executor", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(ExternalShutdownException, KeyboardInterrupt):
            self.executor.spin()

    @property
    def logger(self):
        return self.node.get_logger()

    def add_robot(self, spec: RobotSpec) -> RobotChannel:
        channel = RobotChannel(self.node, spec, lambda: self.sim_time)
        self.channels[spec.name] = channel
        return channel

    def remove_robot(self, name: str) -> None:
        channel = self.channels.pop(name, None)
        if channel is not None:
            channel.destroy()

    def publish_clock(self, sim_time: float) -> None:
        self._clock_msg.clock = stamp(sim_time)
        self.clock_pub.publish(self._clock_msg)

    def publish_markers(
        self,
        sim_time: float,
        obstacles: list[ObstacleSpec],
        robots: list[tuple[str, ModelSpec, tuple[float, float, float], bool]],
    ) -> None:
        """The scene on ~/markers, and each robot's own markers on <ns>/markers; built only for
        topics someone subscribes to (hundreds of robots' markers are not free)."""
        t = stamp(sim_time)
        scene_wanted = self.scene_pub.get_subscription_count() > 0
        scene = MarkerArray(markers=markers.obstacle_markers(obstacles, t) if scene_wanted else [])
        for name, model, pose, in_contact in robots:
            channel = self.channels.get(name)
            own_pub = channel.markers_pub if channel is not None else None
            own_wanted = own_pub is not None and own_pub.get_subscription_count() > 0
            if not (scene_wanted or own_wanted):
                continue
            own = markers.robot_markers(name, model, pose, in_contact, t)
            scene.markers.extend(own)
            if own_pub is not None and own_wanted:
                own_pub.publish(MarkerArray(markers=own))
        if scene_wanted:
            self.scene_pub.publish(scene)

    def close(self) -> None:
        for name in list(self.channels):
            self.remove_robot(name)
        self.executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self.node.destroy_node()
        if self.context.ok():
            rclpy.shutdown(context=self.context)
