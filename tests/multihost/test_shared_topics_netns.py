"""A topic a template shares, between two computers (network namespaces, fleet.testing.netns),
with each transport: published by a ROS tool on rack_a, received by one on rack_b.  With `dds`
DDS carries it by itself; with `zenoh` the agents' bridges do, because the robots' template
declares it (tests/control/data/templates/announcer.launch.yaml.j2).  Before anyone publishes
it, `fleet status` says that no one does."""

from __future__ import annotations

import subprocess
import sys

import pytest
import yaml

from fleet.testing.poll import poll
from tests.control.control_helpers import DATA, make_prefix
from tests.multihost.test_multihost import Fleet, lan  # noqa: F401 (lan: the fixture)

pytestmark = pytest.mark.integration

TOPIC = "/fleet/announcements"
PUBLISH = f"""
import time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("announcer")
publisher = node.create_publisher(String, "{TOPIC}", 10)
for number in range(600):
    publisher.publish(String(data=f"announcement {{number}}"))
    rclpy.spin_once(node, timeout_sec=0.1)
"""
RECEIVE = f"""
import time, rclpy
from std_msgs.msg import String
rclpy.init()
node = rclpy.create_node("listener")
heard = []
node.create_subscription(String, "{TOPIC}", lambda message: heard.append(message.data), 10)
end = time.monotonic() + 60
while not heard and time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.2)
print(heard[0] if heard else "nothing")
"""


@pytest.fixture(params=["dds", "zenoh"])
def shared_fleet(request, lan, tmp_path, ros_domain):  # noqa: F811 (lan: the fixture)
    spec = {
        "fleet": "shared",
        "templates": str(DATA / "templates"),
        "ros": {"domain_id": ros_domain, "use_sim_time": False, "transport": request.param},
        "agents": {"rack_a": {}, "rack_b": {}},
        "defaults": {"template": "announcer", "agent": "rack_a"},
        "robots": [{"name": "a1"}, {"name": "b1", "agent": "rack_b"}],
    }
    (tmp_path / "shared.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    running = Fleet(lan, tmp_path)
    running.transport = request.param
    running.env["AMENT_PREFIX_PATH"] = str(make_prefix(tmp_path / "prefix"))  # the robots' fleet_test sleeper
    running.start()
    try:
        yield running
    finally:
        running.stop_and_expect_nothing_left()


def tool(fleet: Fleet, host: str, script: str) -> list[str]:
    """A ROS tool on `host` set up with `fleet ros-env` as a user would."""
    args = ["ros-env"] + ([] if fleet.transport == "dds" else ["--agent", host])
    exports = fleet.fleet(*args)
    assert exports.returncode == 0, exports.stdout + exports.stderr
    env = dict(pair.split("=", 1) for pair in exports.stdout.split()[1:])
    return fleet.lan.hosts[host].command("env", *(f"{k}={v}" for k, v in env.items()), sys.executable, "-c", script)


def test_a_shared_topic_crosses_computers_with_either_transport(shared_fleet, tmp_path):
    fleet = shared_fleet
    poll(
        lambda: {row["name"] for row in fleet.status()["agents"] if row["online"]},
        until=lambda online: online >= {"rack_a", "rack_b"},
        timeout=60,
        interval=0.5,
        retry_on=(AssertionError,),  # the router is not listening yet
        what="the agents online",
    )
    deploy = fleet.fleet("deploy", str(tmp_path / "shared.yaml"), "--timeout", "90")
    assert deploy.returncode == 0, deploy.stdout + deploy.stderr + fleet.log_tails()
    silent = poll(
        lambda: fleet.status()["shared_topics"].get("shared", []),
        until=lambda rows: any(row["name"] == TOPIC and row["problem"] for row in rows),
        timeout=40,
        interval=1.0,
        what="status to say that no one publishes the announcements",
    )
    assert next(row for row in silent if row["name"] == TOPIC)["problem"].startswith(
        f"shared topic {TOPIC}: no publisher on any agent for"
    )
    with open(tmp_path / "publisher.log", "wb") as log:
        publisher = subprocess.Popen(tool(fleet, "rack_a", PUBLISH), env=fleet.env, stdout=log, stderr=log)
    try:
        listener = tool(fleet, "rack_b", RECEIVE)
        heard = subprocess.run(listener, env=fleet.env, capture_output=True, text=True, timeout=120)
        assert heard.stdout.strip().startswith("announcement"), heard.stdout + heard.stderr + fleet.log_tails()
        poll(
            lambda: fleet.status()["shared_topics"]["shared"],
            until=lambda rows: all(row["problem"] == "" for row in rows if row["name"] == TOPIC),
            timeout=20,
            interval=1.0,
            what="status to see the publisher",
        )
    finally:
        publisher.terminate()
        publisher.wait(timeout=20)
