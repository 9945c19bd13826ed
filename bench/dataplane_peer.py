"""One side of a data-plane benchmark, run as its own process (in a network namespace or not).

    python bench/dataplane_peer.py send ROBOTS SECONDS [FIRST [RATE]]  # /rK/odom (RATE Hz, default 50, reliable), /rK/scan (10 Hz, best effort)
    python bench/dataplane_peer.py receive ROBOTS SECONDS [FIRST [PREFIX]]  # prints one JSON line: latencies and counts
    python bench/dataplane_peer.py participant K SECONDS           # a robot's participant for the discovery benchmark
    python bench/dataplane_peer.py observe ROBOTS SECONDS          # prints the wall time when it matched every robot

A sender first waits until every topic has matched a subscriber, then publishes for SECONDS and
prints how many messages it sent; a receiver counts everything it gets until the sender's data
stops.  Robots FIRST .. FIRST+ROBOTS-1 (several receivers share the robots of one sender), in
namespaces /<PREFIX><index> (default prefix "r").

The discovery environment (ROS_DISCOVERY_SERVER or LOCALHOST) comes from the caller.  Latency is
one-way: header stamps are CLOCK_REALTIME, which network namespaces on one machine share.
"""

from __future__ import annotations

import json
import struct
import sys
import time

import rclpy
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Empty

from fleet.dataplane.take import RawTaker

RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
BEST_EFFORT = QoSProfile(depth=100, reliability=ReliabilityPolicy.BEST_EFFORT)
ODOM_RATE, SCAN_RATE = 50, 10
MATCH_TIMEOUT = 30.0  # s a sender waits for its subscribers
QUIET = 3.0  # s without a message after which a receiver stops


STAMP = struct.Struct("<iI")  # header.stamp (sec, nanosec), after the 4-byte CDR encapsulation
STAMP_OFFSET = 4


def stamped(template: bytearray) -> bytes:
    """A message's CDR bytes with the current time as its header stamp."""
    STAMP.pack_into(template, STAMP_OFFSET, *divmod(time.time_ns(), 1_000_000_000))
    return bytes(template)


def send(node, robots: range, seconds: float, odom_rate: int = ODOM_RATE) -> None:
    odom = [node.create_publisher(Odometry, f"/r{k}/odom", RELIABLE) for k in robots]
    scan = [node.create_publisher(LaserScan, f"/r{k}/scan", BEST_EFFORT) for k in robots]
    deadline = time.monotonic() + MATCH_TIMEOUT
    while time.monotonic() < deadline and not all(p.get_subscription_count() for p in odom + scan):
        rclpy.spin_once(node, timeout_sec=0.1)
    time.sleep(1.0)  # the subscribers' side of the match
    # Serialized once and published as bytes: the sender measures the transport, not Python's
    # conversion of 6,000 messages a second (on a 2-core machine that CPU is the transport's).
    laser = LaserScan()
    laser.ranges = [1.0] * 360
    o, s = bytearray(serialize_message(Odometry())), bytearray(serialize_message(laser))
    begin = time.monotonic()
    end = begin + seconds
    sent = {"odom": 0, "scan": 0}
    tick, period = 0, 1.0 / odom_rate
    next_time = time.monotonic()
    while time.monotonic() < end:
        for pub in odom:
            pub.publish(stamped(o))
        sent["odom"] += len(odom)
        if tick % (odom_rate // SCAN_RATE) == 0:
            for pub in scan:
                pub.publish(stamped(s))
            sent["scan"] += len(scan)
        tick += 1
        next_time += period
        time.sleep(max(0.0, next_time - time.monotonic()))
    # The rate the sender kept up (Python may fall behind 50 Hz with many robots).
    print(json.dumps({"sent": sent, "odom_rate": tick / (time.monotonic() - begin)}), flush=True)
    time.sleep(QUIET + 2)  # reliable data still in flight is resent by this writer


def taken_not_called(_message) -> None:
    """A raw subscription's callback: no executor runs here, the RawTaker takes the messages."""


def receive(node, robots: range, seconds: float, prefix: str = "r") -> None:
    """Takes the messages as bytes (fleet.dataplane.take, as the zenoh bridge does) and reads
    only their stamps: a receiver's own cost stays small beside the transport's."""
    latencies: list[float] = []
    counts = {"odom": 0, "scan": 0}
    subscriptions = []
    for k in robots:
        subscriptions.append(
            (node.create_subscription(Odometry, f"/{prefix}{k}/odom", taken_not_called, RELIABLE, raw=True), "odom")
        )
        subscriptions.append(
            (node.create_subscription(LaserScan, f"/{prefix}{k}/scan", taken_not_called, BEST_EFFORT, raw=True), "scan")
        )
    deadline = time.monotonic() + MATCH_TIMEOUT + seconds + 60
    last = time.monotonic()
    with RawTaker(node, subscriptions) as taker:
        while time.monotonic() < deadline:
            taken = taker.take(50_000_000)
            now = time.time_ns()
            for kind, data in taken:
                counts[kind] += 1
                sec, nanosec = STAMP.unpack_from(data, STAMP_OFFSET)
                latencies.append((now - sec * 1_000_000_000 - nanosec) / 1e6)
            if taken:
                last = time.monotonic()
            elif (counts["odom"] or counts["scan"]) and time.monotonic() - last > QUIET:
                break
    print(json.dumps({"latencies_ms": latencies, "counts": counts}), flush=True)


def participant(node, k: int, seconds: float) -> None:
    node.create_publisher(Empty, f"/r{k}/cmd_vel", RELIABLE)
    node.create_subscription(Empty, f"/r{k}/odom", lambda msg: None, RELIABLE)
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.2)


def observe(node, robots: range, seconds: float) -> None:
    pubs = [node.create_publisher(Empty, f"/r{k}/odom", RELIABLE) for k in robots]
    print(json.dumps({"ready": True}), flush=True)
    start = time.monotonic()
    while time.monotonic() - start < seconds:
        rclpy.spin_once(node, timeout_sec=0.05)
        if all(pub.get_subscription_count() for pub in pubs):
            print(json.dumps({"converged_at": time.time()}), flush=True)
            return
    print(json.dumps({"converged": None, "matched": sum(1 for p in pubs if p.get_subscription_count())}), flush=True)


def main(argv: list[str]) -> int:
    role, number, seconds = argv[0], int(argv[1]), float(argv[2])
    first = int(argv[3]) if len(argv) > 3 else 0
    rclpy.init()
    node = rclpy.create_node(f"bench_{role}_{number}_{first}")
    try:
        if role == "participant":
            participant(node, number, seconds)
        elif role == "receive":
            receive(node, range(first, first + number), seconds, *argv[4:5])
        elif role == "send":
            send(node, range(first, first + number), seconds, *(int(rate) for rate in argv[4:5]))
        else:
            observe(node, range(first, first + number), seconds)
    except ExternalShutdownException:  # SIGTERM: the benchmark is done with this process
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
