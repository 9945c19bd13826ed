"""Helpers for the fleet.nodes tests: an rclpy context of the test's own and a probe node."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import pytest


class Ros:
    """An isolated rclpy context with a probe node the test publishes and listens with."""

    def __init__(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        self.context = Context()
        # No signal handlers: Ctrl-C must stay pytest's.
        rclpy.init(args=[], context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.probe = rclpy.create_node("probe", context=self.context)
        self.executor.add_node(self.probe)
        self.nodes = [self.probe]

    def add(self, node_class: type, *ros_args: str, **kwargs: Any):
        """A node under test in this context, built from ROS arguments as a process would be."""
        cli_args = ["--ros-args", *ros_args] if ros_args else None
        node = node_class(context=self.context, cli_args=cli_args, **kwargs)
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def latest(self, msg_type: type, topic: str, qos: Any = 10) -> list:
        """Subscribe on the probe; the returned list fills with the messages received."""
        received: list = []
        self.probe.create_subscription(msg_type, topic, received.append, qos)
        return received

    def spin_until(self, condition: Callable[[], Any], timeout: float = 5.0) -> Any:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)
            result = condition()
            if result:
                return result
        raise AssertionError(f"condition not met within {timeout} s")

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.02)

    def call(self, client, request, timeout: float = 5.0):
        """A service call through the real service, spinning this context meanwhile."""
        if not client.wait_for_service(timeout_sec=timeout):
            raise AssertionError(f"service {client.srv_name} not available")
        future = client.call_async(request)
        self.spin_until(future.done, timeout)
        return future.result()

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        for node in self.nodes:
            node.destroy_node()
        self.context.try_shutdown()


@pytest.fixture
def ros(ros_env):
    """A fresh rclpy context confined to this test's ROS domain (ros_env set os.environ)."""
    harness = Ros()
    try:
        yield harness
    finally:
        harness.close()
