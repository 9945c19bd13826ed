"""One side of a data-plane benchmark, run as its own process (in a network namespace or not).

    python bench/dataplane_peer.py send ROBOTS SECONDS     # /rK/odom (50 Hz, reliable), /rK/scan (10 Hz, best effort)
    python bench/dataplane_peer.py receive ROBOTS SECONDS  # prints one JSON line: latencies and counts
    python bench/dataplane_peer.py participant K SECONDS   # a robot's participant for the discovery benchmark
    python bench/dataplane_peer.py observe ROBOTS SECONDS  # prints seconds until it matched every robot

The discovery environment (ROS_DISCOVERY_SERVER or LOCALHOST) comes from the caller.  Latency is
one-way: header stamps are CLOCK_REALTIME, which network namespaces on one machine share.
"""

from __future__ import annotations

import json
import sys
import time

import rclpy
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Empty

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
BEST_EFFORT = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
ODOM_RATE, SCAN_RATE = 50, 10
WARMUP = 3.0  # s: discovery and matching before counting


def stamp(msg) -> None:
    now = time.time_ns()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(now, 1_000_000_000)


def send(node, robots: int, seconds: float) -> None:
    odom = [node.create_publisher(Odometry, f"/r{k}/odom", RELIABLE) for k in range(robots)]
    scan = [node.create_publisher(LaserScan, f"/r{k}/scan", BEST_EFFORT) for k in range(robots)]
    o, s = Odometry(), LaserScan()
    s.ranges = [1.0] * 360
    begin = time.monotonic()
    end = begin + seconds
    tick, period = 0, 1.0 / ODOM_RATE
    next_time = time.monotonic()
    while time.monotonic() < end:
        for pub in odom:
            stamp(o)
            pub.publish(o)
        if tick % (ODOM_RATE // SCAN_RATE) == 0:
            for pub in scan:
                stamp(s)
                pub.publish(s)
        tick += 1
        next_time += period
        time.sleep(max(0.0, next_time - time.monotonic()))
    # The rate the sender kept up (Python may fall behind 50 Hz with many robots).
    print(json.dumps({"odom_rate": tick / (time.monotonic() - begin)}), flush=True)


def receive(node, robots: int, seconds: float) -> None:
    latencies: list[float] = []
    counts = {"odom": 0, "scan": 0}
    counting = [False]

    def on(kind):
        def callback(msg):
            if counting[0]:
                counts[kind] += 1
                latencies.append((time.time_ns() - msg.header.stamp.sec * 1_000_000_000 - msg.header.stamp.nanosec) / 1e6)
        return callback

    for k in range(robots):
        node.create_subscription(Odometry, f"/r{k}/odom", on("odom"), RELIABLE)
        node.create_subscription(LaserScan, f"/r{k}/scan", on("scan"), BEST_EFFORT)
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        counting[0] = time.monotonic() - start > WARMUP
        rclpy.spin_once(node, timeout_sec=0.05)
    print(json.dumps({"latencies_ms": latencies, "counts": counts, "window": seconds - WARMUP}), flush=True)


def participant(node, k: int, seconds: float) -> None:
    node.create_publisher(Empty, f"/r{k}/cmd_vel", RELIABLE)
    node.create_subscription(Empty, f"/r{k}/odom", lambda msg: None, RELIABLE)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.2)


def observe(node, robots: int, seconds: float) -> None:
    pubs = [node.create_publisher(Empty, f"/r{k}/odom", RELIABLE) for k in range(robots)]
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        rclpy.spin_once(node, timeout_sec=0.1)
        if all(pub.get_subscription_count() for pub in pubs):
            print(json.dumps({"converged": time.monotonic() - start}), flush=True)
            return
    print(json.dumps({"converged": None, "matched": sum(1 for p in pubs if p.get_subscription_count())}), flush=True)


def main(argv: list[str]) -> int:
    role, number, seconds = argv[0], int(argv[1]), float(argv[2])
    rclpy.init()
    node = rclpy.create_node(f"bench_{role}_{number}")
    try:
        {"send": send, "receive": receive, "participant": participant, "observe": observe}[role](node, number, seconds)
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
