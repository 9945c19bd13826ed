"""A test's own view of a fleet's ROS graph: its own rclpy context and node.

Used by integration tests (ours and users', through the pytest plugin) to look at nodes and
topics, publish and subscribe, and read and change parameters, from outside the fleet's
processes.  It joins `domain_id` when given, else ROS_DOMAIN_ID of this process's environment;
ROS_AUTOMATIC_DISCOVERY_RANGE must be set in the environment before it is created (rclpy reads
it when the context starts).
"""

from __future__ import annotations

import time
from collections import deque
from typing import Any, Callable


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


class RosProbe:
    def __init__(self, name: str = "fleet_test_probe", domain_id: int | None = None):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        rclpy.init(args=[], context=self.context, domain_id=domain_id,
                   signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._publishers: dict[str, Any] = {}

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()

    def __enter__(self) -> "RosProbe":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    # --- waiting -----------------------------------------------------------------------------

    def spin(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, deadline - time.monotonic())))

    def wait_until(self, condition: Callable[[], Any], timeout: float, what: str) -> Any:
        """Spin until condition() is truthy; fail with `what` after `timeout` wall seconds."""
        deadline = time.monotonic() + timeout
        while True:
            result = condition()
            if result:
                return result
            if time.monotonic() > deadline:
                raise AssertionError(f"timed out after {timeout:.0f} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.05)

    # --- graph -------------------------------------------------------------------------------

    def node_names(self) -> set[str]:
        return {f"{ns.rstrip('/')}/{name}" for name, ns in self.node.get_node_names_and_namespaces()}

    def wait_for_nodes(self, names: set[str], timeout: float = 30.0) -> None:
        self.wait_until(lambda: names <= self.node_names(), timeout,
                        f"nodes {sorted(names)} (seen: {sorted(self.node_names())})")

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
        client = self.node.create_client(service_type, name)
        try:
            if not client.wait_for_service(timeout_sec=timeout):
                raise AssertionError(f"service {name} not available after {timeout:.0f} s")
            future = client.call_async(request)
            self.executor.spin_until_future_complete(future, timeout_sec=timeout)
            if not future.done():
                raise AssertionError(f"no answer from {name} after {timeout:.0f} s")
            return future.result()
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
