"""A test's own view of a fleet's ROS graph: its own rclpy context and node.

Used by integration tests (ours and users', through the pytest plugin) to look at nodes and
topics, publish and subscribe, and read and change parameters, from outside the fleet's
processes.  It joins `domain_id` when given, else ROS_DOMAIN_ID of this process's environment;
With `discovery_server` (default: ROS_DISCOVERY_SERVER of the environment), it is a discovery
client of that server, as a fleet's nodes are; without one, discovery stays on this computer.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from fleet.testing.poll import poll


class NoSuchParameter(LookupError):
    """A node was asked for a parameter it does not declare."""


class Subscription:
    """Messages received on one topic, newest last."""

    def __init__(self, keep: int):
        self.messages: deque = deque(maxlen=keep)
        self.count = 0

    def _receive(self, message) -> None:
        self.messages.append(message)
        self.count += 1

    @property
    def last(self):
        return self.messages[-1] if self.messages else None


@contextlib.contextmanager
def _discovery_environment(discovery_server: str | None):
    from fleet.runtime.environment import ros_environment

    wanted = ros_environment(0, base={}, discovery_server=discovery_server)
    if discovery_server:
        # A plain client learns only of the endpoints matching its own; a probe looks at the
        # whole graph (topic lists, publisher counts), as `ros2 topic list` does: a super client.
        wanted["ROS_SUPER_CLIENT"] = "TRUE"
    keys = (
        "ROS_DISCOVERY_SERVER",
        "ROS_SUPER_CLIENT",
        "ROS_AUTOMATIC_DISCOVERY_RANGE",
        "ROS_STATIC_PEERS",
        "FASTDDS_BUILTIN_TRANSPORTS",
    )
    saved = {key: os.environ.get(key) for key in keys}
    try:
        for key in keys:
            if key in wanted:
                os.environ[key] = wanted[key]
            else:
                os.environ.pop(key, None)
        yield
    finally:
        for key, value in saved.items():
            if value is None:
                os.environ.pop(key, None)
            else:
                os.environ[key] = value


class RosProbe:
    def __init__(
        self, name: str = "fleet_test_probe", domain_id: int | None = None, discovery_server: str | None = None
    ):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        discovery_server = discovery_server or os.environ.get("ROS_DISCOVERY_SERVER") or None
        # rmw reads discovery settings from the environment when it creates the participant:
        # set them for that moment only (other probes of this process may use other fleets).
        with _discovery_environment(discovery_server):
            rclpy.init(
                args=[], context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO
            )
            self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._publishers: dict[str, Any] = {}

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()

    def __enter__(self) -> RosProbe:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # --- waiting -----------------------------------------------------------------------------

    def spin(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, deadline - time.monotonic())))

    def wait_until(self, condition: Callable[[], Any], timeout: float, what: str) -> Any:
        """Spin until condition() is truthy and return it; fail with `what` after `timeout` wall
        seconds."""
        __tracebackhide__ = True
        return poll(condition, timeout=timeout, what=what, interval=0.05, pause=self._spin_once)

    def _spin_once(self, seconds: float) -> None:
        self.executor.spin_once(timeout_sec=seconds)

    # --- graph -------------------------------------------------------------------------------

    def node_names(self) -> set[str]:
        return {f"{ns.rstrip('/')}/{name}" for name, ns in self.node.get_node_names_and_namespaces()}

    def wait_for_nodes(self, names: set[str], timeout: float = 30.0) -> None:
        poll(
            self.node_names,
            timeout=timeout,
            what=f"nodes {sorted(names)}",
            until=lambda seen: names <= seen,
            interval=0.05,
            pause=self._spin_once,
            describe=lambda seen: f"nodes {sorted(seen)}",
        )

    def topics(self) -> dict[str, list[str]]:
        return dict(self.node.get_topic_names_and_types())

    # --- topics ------------------------------------------------------------------------------

    def subscribe(self, topic: str, message_type, keep: int = 100, qos=None) -> Subscription:
        """Collect messages of `topic`.  `qos` (an rclpy QoSProfile or a depth) defaults to what
        the topic's publishers offer (publisher_qos)."""
        collector = Subscription(keep)
        self.node.create_subscription(
            message_type, topic, collector._receive, qos if qos is not None else self.publisher_qos(topic)
        )
        return collector

    def publisher_qos(self, topic: str):
        """A subscription QoS every publisher of `topic` in the graph now delivers to: best effort
        if any of them is (a reliable subscription gets nothing from a best-effort publisher),
        else reliable; transient local if all of them are.  Without publishers yet, a guess from
        the name: sensor streams (scan, odom) are best effort."""
        from rclpy.qos import QoSDurabilityPolicy, QoSProfile, QoSReliabilityPolicy, qos_profile_sensor_data

        publishers = self.node.get_publishers_info_by_topic(topic)
        if not publishers:
            return qos_profile_sensor_data if topic.endswith(("scan", "odom")) else 10
        offered = [p.qos_profile for p in publishers]
        best_effort = any(q.reliability == QoSReliabilityPolicy.BEST_EFFORT for q in offered)
        # Latched topics (every publisher transient local) hand their last messages to late joiners.
        latched = all(q.durability == QoSDurabilityPolicy.TRANSIENT_LOCAL for q in offered)
        return QoSProfile(
            depth=10,
            reliability=QoSReliabilityPolicy.BEST_EFFORT if best_effort else QoSReliabilityPolicy.RELIABLE,
            durability=QoSDurabilityPolicy.TRANSIENT_LOCAL if latched else QoSDurabilityPolicy.VOLATILE,
        )

    def publish(self, topic: str, message, match_timeout: float = 5.0) -> None:
        """Publish `message` on `topic`.  The first message of a new publisher waits (up to
        `match_timeout` wall seconds) until every subscriber of the topic in the graph, and at
        least one, is matched with it: sent before, DDS drops it, knowing nobody to send it to.
        (So the first publish to a topic nobody subscribes to takes `match_timeout`.)"""
        publisher = self._publishers.get(topic)
        if publisher is None:
            publisher = self._publishers[topic] = self.node.create_publisher(type(message), topic, 10)

            def matched() -> bool:
                count = publisher.get_subscription_count()
                return count > 0 and count >= self.node.count_subscribers(topic)

            deadline = time.monotonic() + match_timeout
            while not matched() and time.monotonic() < deadline:
                self._spin_once(0.02)  # subscriptions keep receiving meanwhile
        publisher.publish(message)

    def _neighbours(self, service: str) -> str:
        """The nodes in the graph beside a service's node (a mistyped node name shows the right one)."""
        namespace = service.rsplit("/", 2)[0] or "/"
        inside = sorted(n for n in self.node_names() if n.rsplit("/", 1)[0] == namespace.rstrip("/"))
        return f"nodes in {namespace} now: {', '.join(inside) or 'none'}"

    # --- parameters --------------------------------------------------------------------------

    def _call(self, service_type, name: str, request, timeout: float):
        from fleet.runtime.param_helper import call_service

        client = self.node.create_client(service_type, name)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise AssertionError(f"service {name} not available after {timeout:.0f} s; {self._neighbours(name)}")
            spin = lambda future, seconds: self.executor.spin_until_future_complete(future, timeout_sec=seconds)  # noqa: E731
            response = call_service(client, request, spin, timeout)
            if response is None:
                raise AssertionError(f"no answer from {name} after {timeout:.0f} s")
            return response
        finally:
            self.node.destroy_client(client)

    def get_parameters(self, node: str, names: list[str], timeout: float = 20.0) -> list:
        from rcl_interfaces.srv import GetParameters
        from rclpy.parameter import parameter_value_to_python

        result = self._call(GetParameters, f"{node}/get_parameters", GetParameters.Request(names=names), timeout)
        # A node answers with fewer values (none, with rclpy) when a name is not declared.
        if len(result.values) != len(names):
            raise NoSuchParameter(f"node {node} has no parameter {' or '.join(map(repr, names))}")
        return [parameter_value_to_python(value) for value in result.values]

    def set_parameter(self, node: str, name: str, value: Any, timeout: float = 20.0) -> tuple[bool, str]:
        """(accepted, reason) from the node's set_parameters service."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        result = self._call(SetParameters, f"{node}/set_parameters", request, timeout)
        outcome = result.results[0]
        return outcome.successful, outcome.reason
