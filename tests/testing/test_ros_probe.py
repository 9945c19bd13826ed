"""The ROS side of fleet.testing (RosProbe, behind FleetHandle.publish/subscribe/get_param),
between two probes of this process in a domain reserved for the test."""

from __future__ import annotations

import threading
from collections.abc import Iterator

import pytest

from fleet.dataplane.discovery import discovery_server
from fleet.runtime.environment import discovery_server_port, ros_environment
from fleet.testing.isolation import reserve_domain_id
from fleet.testing.ros import NoSuchParameter, RosProbe

pytestmark = pytest.mark.integration


@pytest.fixture
def domain() -> Iterator[int]:
    with reserve_domain_id() as reservation:
        yield reservation.domain_id


@pytest.fixture
def server(domain, tmp_path) -> Iterator[str]:
    """A Fast DDS discovery server of the test's domain, as every deployed fleet has: the probes
    meet through it, as a FleetHandle's probe meets the fleet's nodes."""
    address = f"127.0.0.1:{discovery_server_port(domain)}"
    process = discovery_server(address, ros_environment(domain), tmp_path / "discovery.log")
    process.keep_running()
    try:
        yield address
    finally:
        process.stop()


@pytest.fixture
def node(domain, server) -> Iterator[RosProbe]:
    """A probe standing in for a fleet's node (spun in a thread, so it answers parameter services)."""
    probe = RosProbe("robot_node", domain_id=domain, discovery_server=server)
    spinner = threading.Thread(target=probe.executor.spin, daemon=True)
    spinner.start()
    try:
        yield probe
    finally:
        probe.close()  # ends the spin
        spinner.join(timeout=5)


@pytest.fixture
def probes(domain, server, node) -> Iterator[tuple[RosProbe, RosProbe]]:
    """The test's probe and the node."""
    with RosProbe("test_probe", domain_id=domain, discovery_server=server) as test:
        yield test, node


def test_the_first_published_message_arrives(domain, server, node):
    from std_msgs.msg import String

    received: list[str] = []
    node.node.create_subscription(String, "/robot/command", lambda m: received.append(m.data), 10)
    # A probe created and used at once, as by a test right after its fleet came up: it has
    # discovered nobody yet when it publishes.
    with RosProbe("test_probe", domain_id=domain, discovery_server=server) as test:
        test.publish("/robot/command", String(data="go"))
        test.wait_until(lambda: received, timeout=5, what="the one message published")
    assert received == ["go"]


def test_subscribe_takes_the_qos_a_best_effort_publisher_offers(probes):
    from rclpy.qos import qos_profile_sensor_data
    from std_msgs.msg import String

    test, node = probes
    publisher = node.node.create_publisher(String, "/robot/detections", qos_profile_sensor_data)
    test.wait_until(
        lambda: test.node.get_publishers_info_by_topic("/robot/detections"), timeout=10, what="the publisher"
    )
    detections = test.subscribe("/robot/detections", String)

    def published_and_received():
        publisher.publish(String(data="crate"))
        return detections.count

    test.wait_until(published_and_received, timeout=5, what="a best-effort message")
    assert detections.last.data == "crate"


def test_an_explicit_qos_is_used(probes):
    from rclpy.qos import qos_profile_sensor_data
    from std_msgs.msg import String

    test, _ = probes
    test.subscribe("/robot/anything", String, qos=qos_profile_sensor_data)
    (info,) = test.node.get_subscriptions_info_by_topic("/robot/anything")
    assert info.qos_profile.reliability == qos_profile_sensor_data.reliability


def test_an_undeclared_parameter_is_named_in_the_error(probes):
    test, node = probes
    node.node.declare_parameter("max_speed", 0.4)
    assert test.get_parameters("/robot_node", ["max_speed"]) == [0.4]
    with pytest.raises(NoSuchParameter, match=r"node /robot_node has no parameter 'no_such_param'"):
        test.get_parameters("/robot_node", ["no_such_param"])


def test_a_node_not_there_is_named_with_the_nodes_beside_it(probes):
    test, _ = probes
    test.wait_for_nodes({"/robot_node"}, timeout=10)
    with pytest.raises(
        AssertionError,
        match=r"service /robot_nod/get_parameters not available after 1 s; nodes in / now: .*/robot_node",
    ):
        test.get_parameters("/robot_nod", ["max_speed"], timeout=1)
