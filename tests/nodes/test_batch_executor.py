"""fleet.nodes.batch_executor.BatchExecutor with real rclpy nodes, in a context of the test's own."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import pytest

from fleet.nodes.batch_executor import POLL_PERIOD, BatchExecutor
from fleet.testing.poll import poll


@pytest.fixture
def batch(ros) -> Iterator[BatchExecutor]:
    executor = BatchExecutor(context=ros.context)
    try:
        yield executor
    finally:
        executor.shutdown()


def hosted(ros, batch: BatchExecutor, name: str):
    import rclpy

    node = rclpy.create_node(name, context=ros.context)
    ros.nodes.append(node)  # destroyed by the harness
    batch.add_node(node)
    return node


def spin_until(batch: BatchExecutor, condition, what: str, timeout: float = 5.0, **spin) -> None:
    poll(condition, timeout=timeout, what=what, interval=0.0, pause=lambda _: batch.spin_once(0.05, **spin))


@contextmanager
def spinning(batch: BatchExecutor) -> Iterator[None]:
    """The executor spinning on a thread of its own while the test waits on the harness's."""
    stop = threading.Event()

    def spin() -> None:
        while not stop.is_set():
            batch.spin_once(0.05)

    thread = threading.Thread(target=spin)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def test_every_queued_message_and_a_timer_reach_their_callbacks(ros, batch):
    from std_msgs.msg import Int32

    node = hosted(ros, batch, "listener")
    got: list[int] = []
    ticks: list[int] = []
    node.create_subscription(Int32, "numbers", lambda message: got.append(message.data), 50)
    node.create_timer(0.01, lambda: ticks.append(1))
    publisher = ros.probe.create_publisher(Int32, "numbers", 50)
    spin_until(batch, lambda: publisher.get_subscription_count() and ticks, "the listener matched, its timer ticking")
    for number in range(20):
        publisher.publish(Int32(data=number))
    spin_until(batch, lambda: len(got) >= 20, "20 messages")
    assert got == list(range(20))


def test_a_parameter_service_answers(ros, batch):
    """Services are looked at POLL_PERIOD apart, not at every wait: a call is still answered."""
    from rcl_interfaces.srv import GetParameters

    node = hosted(ros, batch, "configured")
    node.declare_parameter("speed", 0.5)
    client = ros.probe.create_client(GetParameters, "/configured/get_parameters")
    with spinning(batch):
        reply = ros.call(client, GetParameters.Request(names=["speed"]))
    assert [value.double_value for value in reply.values] == [0.5]
    assert POLL_PERIOD <= 0.1  # a person calling `fleet param` does not notice it


def test_a_failing_callback_goes_to_its_node_s_handler_and_the_others_go_on(ros, batch):
    healthy, failing = hosted(ros, batch, "healthy"), hosted(ros, batch, "failing")
    ticks = {"healthy": 0, "failing": 0}

    def tick(name: str) -> None:
        ticks[name] += 1
        if name == "failing":
            time.sleep(POLL_PERIOD)  # the services' look is due right after this batch
            raise RuntimeError("broken sensor")

    healthy.create_timer(0.01, lambda: tick("healthy"))
    failing.create_timer(0.01, lambda: tick("failing"))
    failures: list[tuple[str, str]] = []

    def on_error(node, error: BaseException) -> None:  # as the host does: that robot's nodes go
        failures.append((node.get_name(), str(error)))
        batch.remove_node(node)
        node.destroy_node()

    spin_until(batch, lambda: ticks["healthy"] >= 20, "20 ticks of the healthy node", on_error=on_error)
    assert failures == [("failing", "broken sensor")]
    assert ticks["failing"] == 1


def test_without_a_handler_a_failing_callback_raises(ros, batch):
    node = hosted(ros, batch, "failing")

    def fail() -> None:
        raise RuntimeError("broken sensor")

    node.create_timer(0.01, fail)
    with pytest.raises(RuntimeError, match="broken sensor"):
        for _ in range(100):
            batch.spin_once(0.05)


def test_an_entity_created_after_the_node_was_added_is_waited_on(ros, batch):
    node = hosted(ros, batch, "late")
    batch.spin_once(0.01)  # the wait set is built without the timer
    ticks: list[int] = []
    node.create_timer(0.01, lambda: ticks.append(1))  # rclpy wakes the executor: gathered again
    spin_until(batch, lambda: len(ticks) >= 3, "3 ticks of a timer made later")


def test_a_removed_node_s_callbacks_stop(ros, batch):
    node = hosted(ros, batch, "leaving")
    ticks: list[int] = []
    node.create_timer(0.01, lambda: ticks.append(1))
    spin_until(batch, lambda: ticks, "a tick")
    batch.remove_node(node)
    before = len(ticks)
    for _ in range(10):
        batch.spin_once(0.02)
    assert len(ticks) == before


def test_an_incompatible_qos_warning_still_comes(ros, batch):
    """QoS event handlers are looked at POLL_PERIOD apart; their events must not be lost."""
    from rclpy.event_handler import SubscriptionEventCallbacks
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from std_msgs.msg import Int32

    node = hosted(ros, batch, "strict")
    events: list[object] = []
    node.create_subscription(
        Int32,
        "numbers",
        lambda _: None,
        QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE),
        event_callbacks=SubscriptionEventCallbacks(incompatible_qos=events.append),
    )
    for _ in range(3):  # past the first look at the handlers
        batch.spin_once(0.05)
    ros.probe.create_publisher(Int32, "numbers", QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
    spin_until(batch, lambda: events, "the incompatible QoS event")


def test_a_callback_using_an_entity_it_destroyed_is_its_node_s_fault(ros, batch):
    from std_msgs.msg import Int32

    node = hosted(ros, batch, "careless")
    publisher = node.create_publisher(Int32, "out", 10)

    def publish_after_destroying() -> None:
        node.destroy_publisher(publisher)
        publisher.publish(Int32(data=1))

    node.create_timer(0.01, publish_after_destroying)
    failures: list[tuple[str, str]] = []

    def on_error(failed, error: BaseException) -> None:
        failures.append((failed.get_name(), type(error).__name__))
        batch.remove_node(failed)

    spin_until(batch, lambda: failures, "the fault reported", on_error=on_error)
    assert failures == [("careless", "InvalidHandle")]


def test_an_entity_destroyed_by_an_earlier_callback_of_the_batch_is_skipped(ros, batch):
    node = hosted(ros, batch, "pruner")
    ticks: list[str] = []
    timers: dict[str, Any] = {}

    def tick(name: str, other: str) -> None:
        ticks.append(name)
        if other in timers:
            node.destroy_timer(timers.pop(other))

    timers["a"] = node.create_timer(0.01, lambda: tick("a", "b"))
    timers["b"] = node.create_timer(0.01, lambda: tick("b", "a"))
    time.sleep(0.05)  # both due: one wait finds both ready, and the first to run destroys the other
    failures: list[BaseException] = []
    spin_until(batch, lambda: len(ticks) >= 5, "5 ticks of the timer left", on_error=lambda _, e: failures.append(e))
    assert failures == [] and len(set(ticks)) == 1


def sim_time_nodes(ros, batch: BatchExecutor, *names: str) -> list:
    import rclpy
    from rclpy.parameter import Parameter

    nodes = []
    for name in names:
        node = rclpy.create_node(name, context=ros.context, parameter_overrides=[Parameter("use_sim_time", value=True)])
        ros.nodes.append(node)
        batch.add_node(node)
        nodes.append(node)
    return nodes


def clock_publisher(ros):
    """publishing(at, nodes): a check, true once every node's clock reads `at` seconds, that
    publishes that time on /clock again until then."""
    from rosgraph_msgs.msg import Clock

    clock = ros.probe.create_publisher(Clock, "/clock", 10)

    def publishing(at: int, nodes_now: list):
        def check() -> bool:
            if all(node.get_clock().now().nanoseconds == at * 10**9 for node in nodes_now):
                return True
            message = Clock()
            message.clock.sec = at
            clock.publish(message)
            return False

        return check

    return publishing


def test_every_node_on_sim_time_follows_clock_and_never_goes_back_when_the_reader_s_node_leaves(ros, batch):
    nodes = sim_time_nodes(ros, batch, "a", "b", "c")
    publishing = clock_publisher(ros)
    spin_until(batch, publishing(100, nodes), "every node's clock at /clock's time")
    spin_until(batch, publishing(101, nodes), "every node's clock at the next /clock")

    # The node whose subscription the executor waited on leaves: the others go on, forward only.
    first = nodes.pop(0)
    batch.remove_node(first)
    first.destroy_node()
    ros.nodes.remove(first)
    check, seen = publishing(102, nodes), []

    def forward() -> bool:
        seen.append(nodes[0].get_clock().now().nanoseconds)
        return check()

    spin_until(batch, forward, "the others' clocks at /clock after the reader's node left")
    assert seen == sorted(seen)


def test_a_fault_of_the_node_whose_clock_is_read_leaves_the_others_on_time(ros, batch):
    from rclpy.clock import Clock, ClockType

    reader, other = sim_time_nodes(ros, batch, "reader", "other")
    publishing = clock_publisher(ros)
    spin_until(batch, publishing(100, [reader, other]), "both clocks at /clock's time")

    def fail() -> None:
        raise RuntimeError("broken sensor")

    reader.create_timer(0.01, fail, clock=Clock(clock_type=ClockType.STEADY_TIME))
    batch.spin_once(0.0)  # the timer joins the wait set
    publishing(101, [other])()
    time.sleep(0.05)  # the timer is due and the clock message is in: one batch has both
    failures: list[str] = []

    def on_error(node, error: BaseException) -> None:  # as the host does: that robot's nodes go
        failures.append(node.get_name())
        batch.remove_node(node)
        node.destroy_node()

    spin_until(batch, publishing(101, [other]), "the other clock at the next /clock", on_error=on_error)
    assert failures == ["reader"]
