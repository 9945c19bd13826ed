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

    def subscribe(self, topic: str, message_type, keep: int = 100) -> Subscription:
        from rclpy.qos import qos_profile_sensor_data

        collector = Subscription(keep)
        qos = qos_profile_sensor_data if topic.endswith(("scan", "odom")) else 10
        self.node.create_subscription(message_type, topic, collector._receive, qos)
        return collector

    def publish(self, topic: str, message) -> None:
        publisher = self._publishers.get(topic)
        if publisher is None:
            publisher = self._publishers[topic] = self.node.create_publisher(type(message), topic, 10)
        publisher.publish(message)

    # --- parameters --------------------------------------------------------------------------

    def _call(self, service_type, name: str, request, timeout: float):
        from fleet.runtime.param_helper import call_service

        client = self.node.create_client(service_type, name)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise AssertionError(f"service {name} not available after {timeout:.0f} s")
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
        return [parameter_value_to_python(value) for value in result.values]

    def set_parameter(self, node: str, name: str, value: Any, timeout: float = 20.0) -> tuple[bool, str]:
        """(accepted, reason) from the node's set_parameters service."""
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
        result = self._call(SetParameters, f"{node}/set_parameters", request, timeout)
        outcome = result.results[0]
        return outcome.successful, outcome.reason
