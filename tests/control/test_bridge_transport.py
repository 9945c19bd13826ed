"""The `zenoh` transport end to end: two bridges on the fleet router, each on its own ROS domain
(standing for two computers), real rclpy publishers and subscribers on either side.

Checked: a reliable topic's bursts cross whole and in order (the exporter batches them); messages
of camera-image size, larger than a Zenoh batch, cross whole; a latched (transient local) topic's
message reaches an agent whose bridge starts after it was published; a topic no agent brings in
is not sent."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from fleet.dataplane.receive_buffers import RECEIVE_BUFFER_BYTES, RMEM_MAX
from fleet.runtime.environment import domain_ports
from fleet.testing.isolation import discovery_served, reserve_domain_id
from fleet.testing.poll import poll
from tests.control.control_helpers import thread_names, zenoh_runtimes

pytestmark = pytest.mark.integration

ROUTES = [
    {"name": "/a1/odom", "type": "std_msgs/msg/String", "reliable": True, "depth": 100},
    {"name": "/map", "type": "std_msgs/msg/String", "reliable": True, "transient_local": True, "depth": 1},
    {"name": "/a1/unused", "type": "std_msgs/msg/String", "reliable": True},
]

# A publisher: waits for a subscriber (unless latched), sends COUNT messages in bursts of 100,
# message k being str(k) padded with dots to SIZE characters (if SIZE is given).
PUBLISH = """
import sys, time, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy
from std_msgs.msg import String
topic, count, latched = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "latched"
size = int(sys.argv[4]) if len(sys.argv) > 4 else 0
rclpy.init()
node = rclpy.create_node("publisher")
qos = QoSProfile(depth=1 if latched else 100, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
pub = node.create_publisher(String, topic, qos)
while not latched and not pub.get_subscription_count():
    time.sleep(0.1)
time.sleep(1.0)
for k in range(count):
    pub.publish(String(data=str(k).ljust(size, '.')))
    if k % 100 == 99:
        time.sleep(0.1)
print("sent", flush=True)
sys.stdin.read()  # until the test closes stdin: latched data stays available
"""

# A subscriber: says "ready" once matched with the importing bridge's publisher (a volatile
# message sent before would be lost to it in DDS, bridge or not), then prints one JSON line with
# what it received once nothing came for 3 s: each message without its padding, and its length.
# Its queue holds every message the test sends: rclpy runs one callback per spin here, and under
# load (two suites at once on 2 cores) that fell behind the bursts of 100 every 0.1 s, so a
# queue of 100 gave up its oldest messages (660 of 1000 arrived), in DDS, bridge or not.
SUBSCRIBE = """
import json, sys, time, rclpy
from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy
from std_msgs.msg import String
topic, latched = sys.argv[1], sys.argv[2] == "latched"
rclpy.init()
node = rclpy.create_node("subscriber")
got, sizes, last = [], [], [time.monotonic()]
qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
def on(msg):
    got.append(msg.data.rstrip(".")); sizes.append(len(msg.data)); last[0] = time.monotonic()
sub = node.create_subscription(String, topic, on, qos)
deadline = time.monotonic() + 60
while time.monotonic() < deadline and not sub.get_publisher_count():  # the bridge's publisher
    rclpy.spin_once(node, timeout_sec=0.05)
print("ready", flush=True)
while time.monotonic() < deadline and not (got and time.monotonic() - last[0] > 3.0):
    rclpy.spin_once(node, timeout_sec=0.05)
print(json.dumps({"data": got, "sizes": sizes}), flush=True)
"""


class Bridges:
    def __init__(self, tmp_path: Path, endpoint: str) -> None:
        self.tmp_path, self.endpoint = tmp_path, endpoint
        self.processes: list[subprocess.Popen] = []
        self.pids: dict[str, int] = {}

    def start(self, agent: str, env: dict[str, str], exports: list, imports: list) -> Path:
        config = self.tmp_path / f"{agent}.bridge.json"
        config.write_text(
            json.dumps(
                {
                    "fleet": "lan",
                    "agent": agent,
                    "connect": [self.endpoint],
                    "zenoh_config": None,
                    "exports": exports,
                    "imports": imports,
                }
            )
        )
        log = self.tmp_path / f"{agent}.bridge.log"
        with open(log, "wb") as out:
            self.processes.append(
                subprocess.Popen(
                    [sys.executable, "-m", "fleet.dataplane.bridge", str(config)],
                    env=env,
                    stdout=out,
                    stderr=subprocess.STDOUT,
                )
            )
        poll(log.read_text, until=lambda text: "bridge of fleet lan" in text, timeout=60, what=f"bridge {agent} up")
        self.pids[agent] = self.processes[-1].pid
        return log

    def stop(self) -> None:
        for process in self.processes:
            process.terminate()
        for process in self.processes:
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


def ros_process(script: str, env: dict[str, str], *args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-c", script, *args],
        env=env,
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )


def ready(subscriber: subprocess.Popen) -> None:
    assert subscriber.stdout is not None and subscriber.stdout.readline().strip() == "ready"


def received(subscriber: subprocess.Popen) -> dict[str, list]:
    """{"data": [each message without its padding], "sizes": [each message's length]}"""
    out, _ = subscriber.communicate(timeout=90)
    return json.loads(out.strip().splitlines()[-1])


@pytest.fixture
def two_domains(domain_id, tmp_path):
    """Two computers' DDS: the environments of two domains, each with its own discovery server."""
    with (
        reserve_domain_id() as other,
        discovery_served(domain_id, tmp_path / "rack.discovery.log") as rack,
        discovery_served(other.domain_id, tmp_path / "sim.discovery.log") as sim,
    ):
        yield rack, sim


@pytest.fixture
def bridges(fresh_cluster, tmp_path):
    fresh_cluster.start_router()
    bridges = Bridges(tmp_path, fresh_cluster.endpoint)
    try:
        yield bridges
    finally:
        bridges.stop()


def test_a_reliable_topic_crosses_whole_and_in_order(bridges, two_domains):
    rack, sim = two_domains
    sim_log = bridges.start("sim_host", sim, exports=[], imports=ROUTES)
    rack_log = bridges.start("rack_a", rack, exports=ROUTES, imports=[])
    subscriber = ros_process(SUBSCRIBE, sim, "/a1/odom", "volatile")
    ready(subscriber)
    publisher = ros_process(PUBLISH, rack, "/a1/odom", "1000", "volatile")
    try:
        got = received(subscriber)["data"]
    finally:
        publisher.kill()
        publisher.wait()
    # The importing bridge read them on Zenoh's application thread (fleet.dataplane.bridge.ZENOH_RUNTIME).
    assert "rx" not in zenoh_runtimes(thread_names(bridges.pids["sim_host"]))
    bridges.stop()  # their last lines count what went out and came in: where a loss happened
    counts = [line for log in (rack_log, sim_log) for line in log.read_text().splitlines() if "stopping:" in line]
    wanted = [str(k) for k in range(1000)]
    gap = next((k for k, (a, b) in enumerate(zip(got, wanted, strict=False)) if a != b), min(len(got), 1000))
    assert got == wanted, f"received {len(got)} of 1000, in order up to {gap}; bridges: {counts}"
    # /a1/unused had no importer: nothing of it went.
    assert "stopping: 1000 messages out" in rack_log.read_text()


IMAGE_BYTES = 2_000_000  # a camera image: 30 times a Zenoh batch (64 KiB), so Zenoh fragments it


def test_messages_larger_than_a_zenoh_batch_cross_whole(bridges, two_domains):
    rack, sim = two_domains
    bridges.start("sim_host", sim, exports=[], imports=ROUTES)
    bridges.start("rack_a", rack, exports=ROUTES, imports=[])
    subscriber = ros_process(SUBSCRIBE, sim, "/a1/odom", "volatile")
    ready(subscriber)
    publisher = ros_process(PUBLISH, rack, "/a1/odom", "5", "volatile", str(IMAGE_BYTES))
    try:
        got = received(subscriber)
    finally:
        publisher.kill()
        publisher.wait()
    assert got == {"data": ["0", "1", "2", "3", "4"], "sizes": [IMAGE_BYTES] * 5}


def test_a_latched_message_reaches_an_agent_whose_bridge_starts_later(bridges, two_domains):
    rack, sim = two_domains
    bridges.start("rack_a", rack, exports=ROUTES, imports=[])
    publisher = ros_process(PUBLISH, rack, "/map", "1", "latched")
    try:
        assert publisher.stdout is not None and publisher.stdout.readline().strip() == "sent"
        bridges.start("sim_host", sim, exports=[], imports=ROUTES)
        subscriber = ros_process(SUBSCRIBE, sim, "/map", "latched")
        assert received(subscriber)["data"] == ["0"]
    finally:
        publisher.kill()
        publisher.wait()


def receive_buffers(pid: int, domain_id: int) -> list[int]:
    """The receive buffers (bytes, as the kernel reports them) of `pid`'s UDP sockets bound to
    ports of the domain's RTPS block (`ss` lists a socket, then its memory on the next line)."""
    ports = domain_ports(domain_id)
    listing = subprocess.run(["ss", "-u", "-a", "-m", "-p", "-n"], capture_output=True, text=True, check=True).stdout
    found = re.findall(r':(\d+)\s+\S+\s+users:\(\("[^"]*",pid=(\d+),[^\n]*\n\s*skmem:\(r\d+,rb(\d+)', listing)
    return [int(rb) for port, owner, rb in found if int(owner) == pid and int(port) in ports]


def test_an_exporting_bridge_s_sockets_hold_a_fleet_s_burst(bridges, ros_env, ros_domain):
    """The world publishes every robot's scans at once; in the default 212 KiB buffer, 100
    robots' burst overflowed and the kernel dropped 5% of the best-effort scans.  Linux grants
    at most net.core.rmem_max and reports twice what was granted."""
    bridges.start("sim_host", ros_env, exports=ROUTES, imports=[])
    buffers = receive_buffers(bridges.pids["sim_host"], ros_domain)
    assert buffers, "the bridge has no UDP socket in its domain's ports"
    granted = min(RECEIVE_BUFFER_BYTES, int(RMEM_MAX.read_text()))
    assert min(buffers) >= 2 * granted, buffers
