"""ROS side of the world: one rclpy node, per-robot publishers and subscriptions, /clock.

The world runs this in a process of its own (fleet.world.ros_process), beside the physics
process.  Robots are known by their physics rows: `set_robots` gives the layout, publications
name rows, `inputs` returns the latest command, battery and odom subscribers of every row as one
snapshot.

Threading: the executor spins in a background thread and its callbacks only store the latest
command or battery reading.  Odometry, ground truth and scans of all robots are kept serialized
(fleet.world.frames): a batch of them is written with numpy and published as bytes, so a message
costs ~3 us instead of ~20.
"""

from __future__ import annotations

import contextlib
import math
import threading
import time
from typing import NamedTuple

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
from fleet.world.description import ObstacleSpec, RobotSpec
from fleet.world.frames import Field, SerializedFrames
from fleet.world.inputs import NEVER, RobotInputs, fresh_battery

# Best-effort subscriptions match both reliable and best-effort publishers; reliable publishers
# match both kinds of subscribers (RViz, Nav2's sensor-data QoS, ros2 topic echo).
_SUB_QOS = QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT)
_PUB_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def stamp(sim_time: float) -> Time:
    sec = math.floor(sim_time)
    return Time(sec=sec, nanosec=min(round((sim_time - sec) * 1e9), 999_999_999))


class Command(NamedTuple):  # a tuple: the commands of all robots make one numpy array cheaply
    linear: float = 0.0
    angular: float = 0.0
    wall: float = NEVER  # time.monotonic() when received
    sim: float = NEVER  # sim time when received


class RobotChannel:
    """Everything ROS about one robot: its publishers, subscriptions and the latest inputs."""

    def __init__(self, node: Node, spec: RobotSpec, clock_source) -> None:
        self.spec = spec
        self.node = node
        ns = spec.namespace.rstrip("/")
        self.command = Command()
        self.battery = (math.nan, NEVER)  # percentage, time.monotonic() when received
        self._sim_now = clock_source
        self.odom_pub = node.create_publisher(Odometry, f"{ns}/odom", _PUB_QOS)
        self.scan_pub = node.create_publisher(LaserScan, f"{ns}/scan", _PUB_QOS)
        self.truth_pub = (
            node.create_publisher(PoseStamped, f"{ns}/ground_truth", _PUB_QOS) if spec.ground_truth else None
        )
        self.cmd_sub = node.create_subscription(Twist, f"{ns}/cmd_vel", self._on_cmd, _SUB_QOS)
        self.battery_sub = node.create_subscription(BatteryState, f"{ns}/battery", self._on_battery, _SUB_QOS)
        self.markers_pub = node.create_publisher(MarkerArray, f"{ns}/markers", _PUB_QOS)

    # executor thread: store and return
    def _on_cmd(self, msg: Twist) -> None:
        self.command = Command(msg.linear.x, msg.angular.z, time.monotonic(), self._sim_now())

    def _on_battery(self, msg: BatteryState) -> None:
        self.battery = (float(msg.percentage), time.monotonic())

    def destroy(self) -> None:
        for entity in (self.odom_pub, self.scan_pub, self.truth_pub, self.markers_pub):
            if entity is not None:
                self.node.destroy_publisher(entity)
        self.node.destroy_subscription(self.cmd_sub)
        self.node.destroy_subscription(self.battery_sub)


_STAMP = (Field("header.stamp.sec", "i4"), Field("header.stamp.nanosec", "u4"))
_ODOM_FIELDS = (
    *_STAMP,
    *(Field(f"pose.pose.{name}", "f8") for name in ("position.x", "position.y", "orientation.z", "orientation.w")),
    *(Field(f"twist.twist.{name}", "f8") for name in ("linear.x", "linear.y", "angular.z")),
)
_TRUTH_FIELDS = (
    *_STAMP,
    *(Field(f"pose.{name}", "f8") for name in ("position.x", "position.y", "orientation.z", "orientation.w")),
)


def odom_template(spec: RobotSpec) -> Odometry:
    msg = Odometry()
    msg.header.frame_id = f"{spec.name}/odom"
    msg.child_frame_id = f"{spec.name}/base_link"
    return msg


def truth_template(spec: RobotSpec) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "world"
    return msg


def scan_template(spec: RobotSpec) -> LaserScan:
    lidar = spec.lidar
    msg = LaserScan()
    msg.header.frame_id = f"{spec.name}/base_scan"
    msg.angle_min = lidar.angle_min
    msg.angle_increment = lidar.increment
    msg.angle_max = lidar.angle_min + lidar.increment * (lidar.beams - 1)
    msg.time_increment = 0.0  # all beams are taken at the same instant
    msg.scan_time = 1.0 / lidar.rate
    msg.range_min = lidar.range_min
    msg.range_max = lidar.range_max
    msg.ranges = [0.0] * lidar.beams
    return msg


def _write_stamp(frames: SerializedFrames, slots: np.ndarray, sim_time: float) -> None:
    t = stamp(sim_time)
    frames.write("header.stamp.sec", slots, t.sec)
    frames.write("header.stamp.nanosec", slots, t.nanosec)


class Outbox:
    """The serialized odometry, ground truth and scans of a set of robots (fleet.world.frames),
    built once for the robots present (one slot per row) and published in batches by row."""

    def __init__(self, channels: list[RobotChannel]) -> None:
        self.odom_pubs = [channel.odom_pub for channel in channels]
        self.odom = SerializedFrames([odom_template(c.spec) for c in channels], _ODOM_FIELDS)
        # odom's origin is the robot's nominal spawn pose from world.yaml (not where a restarted
        # world put it back), so odom stays continuous when the world restarts.
        self.origin = np.array([(c.spec.pose.x, c.spec.pose.y, c.spec.pose.yaw) for c in channels]).reshape(-1, 3)
        with_truth = [c for c in channels if c.truth_pub is not None]
        self.truth_slot = np.full(len(channels), -1, dtype=np.int64)
        self.truth_slot[[i for i, c in enumerate(channels) if c.truth_pub is not None]] = np.arange(len(with_truth))
        self.truth_pubs = [c.truth_pub for c in with_truth]
        self.truth = SerializedFrames([truth_template(c.spec) for c in with_truth], _TRUTH_FIELDS)
        # scans by beam count (the length of the ranges field): (frames, slot -> row, publishers)
        self.scans: dict[int, tuple[SerializedFrames, np.ndarray, list]] = {}
        for beams in sorted({c.spec.lidar.beams for c in channels}):
            same = [c for c in channels if c.spec.lidar.beams == beams]
            rows = np.full(len(channels), -1, dtype=np.int64)
            rows[[i for i, c in enumerate(channels) if c.spec.lidar.beams == beams]] = np.arange(len(same))
            fields = (*_STAMP, Field("ranges", "f4", beams))
            frames = SerializedFrames([scan_template(c.spec) for c in same], fields)
            self.scans[beams] = (frames, rows, [c.scan_pub for c in same])

    def publish_odom(self, slots: np.ndarray, sim_time: float, poses: np.ndarray, velocities: np.ndarray) -> None:
        """poses (S, 3) x, y, yaw in the world; velocities (S, 3) linear, lateral, angular in the body frame."""
        ox, oy, oyaw = self.origin[slots].T
        c, s = np.cos(oyaw), np.sin(oyaw)
        dx, dy = poses[:, 0] - ox, poses[:, 1] - oy
        half = (poses[:, 2] - oyaw) / 2
        odom = self.odom
        _write_stamp(odom, slots, sim_time)
        odom.write("pose.pose.position.x", slots, c * dx + s * dy)
        odom.write("pose.pose.position.y", slots, -s * dx + c * dy)
        odom.write("pose.pose.orientation.z", slots, np.sin(half))
        odom.write("pose.pose.orientation.w", slots, np.cos(half))
        odom.write("twist.twist.linear.x", slots, velocities[:, 0])
        odom.write("twist.twist.linear.y", slots, velocities[:, 1])
        odom.write("twist.twist.angular.z", slots, velocities[:, 2])
        pubs = self.odom_pubs
        for slot, data in zip(slots.tolist(), odom.messages(slots), strict=True):
            pubs[slot].publish(data)
        truth_slots = self.truth_slot[slots]
        has_truth = truth_slots >= 0
        if has_truth.any():
            rows, world = truth_slots[has_truth], poses[has_truth]
            truth = self.truth
            _write_stamp(truth, rows, sim_time)
            truth.write("pose.position.x", rows, world[:, 0])
            truth.write("pose.position.y", rows, world[:, 1])
            truth.write("pose.orientation.z", rows, np.sin(world[:, 2] / 2))
            truth.write("pose.orientation.w", rows, np.cos(world[:, 2] / 2))
            for row, data in zip(rows.tolist(), truth.messages(rows), strict=True):
                self.truth_pubs[row].publish(data)

    def publish_scans(self, slots: np.ndarray, sim_time: float, ranges: np.ndarray) -> None:
        """ranges (S, beams), one scan per slot."""
        frames, rows_of, pubs = self.scans[ranges.shape[1]]
        rows = rows_of[slots]
        _write_stamp(frames, rows, sim_time)
        frames.write("ranges", rows, ranges.astype(np.float32))
        for row, data in zip(rows.tolist(), frames.messages(rows), strict=True):
            pubs[row].publish(data)


SUBSCRIBERS_PERIOD = 1.0  # s (wall) between counts of each odom's subscribers: they change rarely


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
        self.rows: list[RobotChannel] = []  # the channels by physics row
        self.obstacles: list[ObstacleSpec] = []
        self.generation = 0  # of the layout (rows and obstacles) last set
        self._outbox: Outbox | None = None
        self._subscribers = np.zeros(0, dtype=np.int64)
        self._subscribers_at = -math.inf  # time.monotonic() of the last count
        self.sim_time = 0.0  # the latest sim time published, read by callbacks for stamps
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._thread = threading.Thread(target=self._spin, name="ros-executor", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        with contextlib.suppress(ExternalShutdownException, KeyboardInterrupt):
            self.executor.spin()

    def set_robots(self, generation: int, robots: list[RobotSpec], obstacles: list[ObstacleSpec]) -> None:
        """The robots by physics row, and the obstacles: robots that are new or changed get their
        publishers and subscriptions, robots no longer present lose them."""
        wanted = {spec.name: spec for spec in robots}
        for name, channel in list(self.channels.items()):
            if wanted.get(name) != channel.spec:
                channel.destroy()
                del self.channels[name]
        for spec in robots:
            if spec.name not in self.channels:
                self.channels[spec.name] = RobotChannel(self.node, spec, lambda: self.sim_time)
        self.rows = [self.channels[spec.name] for spec in robots]
        self.obstacles = list(obstacles)
        self.generation = generation
        self._outbox = None
        self._subscribers_at = -math.inf

    def inputs(self) -> RobotInputs:
        """The latest command, battery and odom subscribers of every row."""
        rows = self.rows
        now = time.monotonic()
        if now - self._subscribers_at > SUBSCRIBERS_PERIOD:
            self._subscribers = np.array([c.odom_pub.get_subscription_count() for c in rows], dtype=np.int64)
            self._subscribers_at = now
        commands = np.array([c.command for c in rows], dtype=float).reshape(-1, 4)
        battery = fresh_battery([c.battery for c in rows], now)
        return RobotInputs(self.generation, commands, battery, self._subscribers)

    def hold(self, commands: np.ndarray) -> None:
        """(n, 2) linear and angular speed by row that never expire: how a benchmark drives."""
        for channel, (linear, angular) in zip(self.rows, commands.tolist(), strict=True):
            channel.command = Command(linear, angular, math.inf, math.inf)

    @property
    def outbox(self) -> Outbox:
        """The serialized messages of the robots present (rebuilt after robots came or went)."""
        if self._outbox is None:
            self._outbox = Outbox(self.rows)
        return self._outbox

    def publish_odom(self, rows: np.ndarray, sim_time: float, poses: np.ndarray, velocities: np.ndarray) -> None:
        self.sim_time = sim_time
        self.outbox.publish_odom(rows, sim_time, poses, velocities)

    def publish_scans(self, rows: np.ndarray, sim_time: float, ranges: np.ndarray) -> None:
        self.sim_time = sim_time
        self.outbox.publish_scans(rows, sim_time, ranges)

    def publish_clock(self, sim_time: float) -> None:
        self.sim_time = sim_time
        self._clock_msg.clock = stamp(sim_time)
        self.clock_pub.publish(self._clock_msg)

    def publish_markers(self, sim_time: float, poses: np.ndarray, touching: set[str]) -> None:
        """The scene on ~/markers, and each robot's own markers on <ns>/markers (poses by row);
        built only for topics someone subscribes to (hundreds of robots' markers are not free)."""
        t = stamp(sim_time)
        scene_wanted = self.scene_pub.get_subscription_count() > 0
        scene = MarkerArray(markers=markers.obstacle_markers(self.obstacles, t) if scene_wanted else [])
        for channel, pose in zip(self.rows, poses.tolist(), strict=True):
            own_wanted = channel.markers_pub.get_subscription_count() > 0
            if not (scene_wanted or own_wanted):
                continue
            name = channel.spec.name
            own = markers.robot_markers(name, channel.spec.model, tuple(pose), name in touching, t)
            scene.markers.extend(own)
            if own_wanted:
                channel.markers_pub.publish(MarkerArray(markers=own))
        if scene_wanted:
            self.scene_pub.publish(scene)

    def close(self) -> None:
        for channel in self.channels.values():
            channel.destroy()
        self.channels.clear()
        self.rows = []
        self.executor.shutdown(timeout_sec=1.0)
        self._thread.join(timeout=2.0)
        self.node.destroy_node()
        if self.context.ok():
            rclpy.shutdown(context=self.context)
