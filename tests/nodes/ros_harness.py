"""An rclpy context of the test's own, holding the nodes under test and a probe node."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from fleet.testing.poll import poll


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

    def spin_until(self, condition: Callable[[], Any], timeout: float = 5.0, what: str | None = None) -> Any:
        """Spin until condition() is truthy, and return that."""
        __tracebackhide__ = True
        return poll(
            condition,
            timeout=timeout,
            what=what or str(getattr(condition, "__name__", "condition")),
            interval=0.02,
            pause=self._spin_once,
        )

    def _spin_once(self, seconds: float) -> None:
        self.executor.spin_once(timeout_sec=seconds)

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
