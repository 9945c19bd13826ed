"""BatchExecutor: spins many rclpy nodes on one thread, one wait for every batch of callbacks.

rclpy's SingleThreadedExecutor gathers every entity of every node anew in Python before each
wait, enters each one's handle, and matches each QoS event handler against a list of all of them
(quadratic in the handlers: a robot's three fleet nodes have 36, one per publisher or
subscription and kind of event).  A host of 10 robots on sim time used 76% of a core, most of it
there (py-spy), for callbacks that themselves took a few percent; with this executor 36%
(bench/README.md, "A simulated fleet").  The hosts (isolation: agent) and the node processes of
the other isolations (fleet.nodes.common.run) spin with it.  It

- keeps the entity lists and the wait set between waits, and gathers them again only when a node
  is added or removed or a node creates or destroys an entity (rclpy then calls `wake`);
- after a wait, runs every callback found ready, taking every message or request queued at a
  ready subscription or service, then waits again;
- waits on one of the /clock subscriptions that rclpy makes for every node on sim time, and
  hands each message it takes to every node's time source: a host of 25 robots would otherwise
  take and convert the same message 75 times, 100 times a second;
- looks at the nodes' services (parameter services: 21 of a robot's 35 entities, seldom called)
  and QoS event handlers (incompatible QoS or type: warnings for the logs) in a wait set of their
  own, without waiting, POLL_PERIOD apart, rather than at every wait: the cost of a wait grows
  with the entities in it, in Python and in the middleware, and a host of 10 robots on sim time
  waits about 240 times a second.  A request or event stays queued in the middleware until
  taken, so it is served at most POLL_PERIOD late.

Its limits, which fleet's nodes stay within: callbacks run one at a time on the spinning thread
(callback groups are not consulted), a callback that awaits something not yet done is an error,
and nodes, and their entities, are created and destroyed on the spinning thread, between waits.
"""

from __future__ import annotations

import inspect
import time
from collections.abc import Callable, Iterable
from typing import Any

from rclpy.event_handler import EventHandler
from rclpy.guard_condition import GuardCondition
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.subscription import Subscription
from rclpy.time_source import TimeSource
from rclpy.utilities import get_default_context
from rclpy.waitable import NumberOfEntities

POLL_PERIOD = 0.05  # s between two looks at the services and QoS event handlers

ErrorHandler = Callable[[Any, BaseException], None]  # (node, exception)


class BatchExecutor:
    """`add_node`, `remove_node`, `spin_once(timeout_sec)`, `wake` (any thread), `shutdown`."""

    def __init__(self, context: Any = None) -> None:
        self._context = context if context is not None else get_default_context()
        self._wake: Any = GuardCondition(None, None, self._context)  # None once shut down
        self._context.on_shutdown(self.wake)
        self._nodes: list[Any] = []
        self._live: set[int] = set()  # id() of the nodes added, for skipping a removed node's callbacks
        self._stale = True  # the entity lists and wait sets must be gathered again
        self._wait_set: Any = None
        self._polled_wait_set: Any = None  # the services and QoS event handlers
        self._next_poll = 0.0
        self._handles: dict[str, list[Any]] = {}  # kind -> its handles (services: polled, the rest: waited on)
        self._entities: dict[str, dict[int, tuple[Any, Any]]] = {}  # kind -> pointer -> (entity, node)
        self._waitables: list[tuple[Any, Any]] = []  # (waitable, node), other than QoS events
        self._events: list[tuple[Any, Any]] = []  # (QoS event handler, node)
        self._clocks: list[tuple[Any, Any]] = []  # (a TimeSource's /clock subscription, node)

    # -- the nodes --

    def add_node(self, node: Any) -> bool:
        if id(node) in self._live:
            return False
        self._nodes.append(node)
        self._live.add(id(node))
        node.executor = self  # rclpy's node then calls wake() when it creates or destroys an entity
        self.wake()
        return True

    def remove_node(self, node: Any) -> None:
        if id(node) not in self._live:
            return
        self._nodes.remove(node)
        self._live.discard(id(node))
        node.executor = None
        self.wake()

    def get_nodes(self) -> list[Any]:
        return list(self._nodes)

    def wake(self) -> None:
        """End the current wait; the next one gathers the entities again (they may have changed)."""
        self._stale = True
        if self._wake is not None:
            self._wake.trigger()

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        for node in list(self._nodes):
            self.remove_node(node)
        if self._wake is not None:
            self._wake.destroy()
            self._wake = None
        return True

    # -- spinning --

    def spin_once(self, timeout_sec: float | None = None, on_error: ErrorHandler | None = None) -> None:
        """Wait up to `timeout_sec` (None: no limit), and at most until the next look at the
        services and QoS events, for work; then run every callback found ready.
        An exception escaping a callback goes to `on_error(node, exception)`, and that node's
        further callbacks in this batch run only while it is still added; without `on_error` it
        propagates, as from rclpy's executors."""
        if self._wake is None:
            return
        if self._stale:
            self._gather()
        wait_set = self._wait_set
        wait_set.clear_entities()
        for kind, add in (
            ("subscription", wait_set.add_subscription),
            ("timer", wait_set.add_timer),
            ("client", wait_set.add_client),
            ("guard_condition", wait_set.add_guard_condition),
        ):
            for handle in self._handles[kind]:
                add(handle)
        for waitable, _ in self._waitables:
            waitable.add_to_wait_set(wait_set)
        until_poll = max(0.0, self._next_poll - time.monotonic())
        timeout = until_poll if timeout_sec is None or timeout_sec < 0 else min(timeout_sec, until_poll)
        wait_set.wait(int(timeout * 1e9))
        if not self._context.ok():
            return
        for kind in ("timer", "subscription", "client", "guard_condition"):
            entities = self._entities[kind]
            for pointer in wait_set.get_ready_entities(kind):
                found = entities.get(pointer)
                if found is None:
                    continue
                if kind == "subscription" and self._clocks and found[0] is self._clocks[0][0]:
                    self._share_clock(on_error)
                else:
                    self._run(found[1], _CALLS[kind], found[0], on_error)
        for waitable, node in self._waitables:
            if waitable.is_ready(wait_set):
                self._run(node, _call_waitable, waitable, on_error)
        if time.monotonic() >= self._next_poll:
            self._poll(on_error)

    def _left(self, node: Any, entity: Any) -> bool:
        """`node` was removed (a fault), or `entity` destroyed, by an earlier callback of this batch."""
        return id(node) not in self._live or (self._stale and not _still_has(node, entity))

    def _run(self, node: Any, call: Callable[[Any], None], entity: Any, on_error: ErrorHandler | None) -> None:
        if self._left(node, entity):
            return
        try:
            call(entity)
        except Exception as error:
            if on_error is None:
                raise
            on_error(node, error)

    def _share_clock(self, on_error: ErrorHandler | None) -> None:
        """The latest /clock message, taken from the one clock subscription waited on, to every
        node's time source.  The others' readers are never taken from: DDS keeps only their
        latest message (depth 1), so whichever is waited on next after a node leaves holds the
        current time, not an old one."""
        reader, reader_node = self._clocks[0]
        if self._left(reader_node, reader):  # the next wait is on another node's
            return
        latest = None
        while (taken := reader.handle.take_message(reader.msg_type, reader.raw)) is not None:
            latest = taken[0]
        if latest is None:
            return
        for subscription, node in list(self._clocks):
            self._run(node, lambda s: _finish(s.callback(latest)), subscription, on_error)

    def _poll(self, on_error: ErrorHandler | None) -> None:
        """Serve the services' queued requests and the QoS events that came, without waiting."""
        self._next_poll = time.monotonic() + POLL_PERIOD
        if self._stale:  # a callback of this batch removed a node (a fault): its handles are gone
            self._gather()
        if not (self._handles["service"] or self._events):
            return
        wait_set = self._polled_wait_set
        wait_set.clear_entities()
        for handle in self._handles["service"]:
            wait_set.add_service(handle)
        for handler, _ in self._events:
            handler.add_to_wait_set(wait_set)
        wait_set.wait(0)
        for pointer in wait_set.get_ready_entities("service"):
            found = self._entities["service"].get(pointer)
            if found is not None:
                self._run(found[1], _call_service, found[0], on_error)
        for handler, node in self._events:
            if handler.is_ready(wait_set):
                self._run(node, _call_waitable, handler, on_error)

    def _gather(self) -> None:
        self._stale = False
        subscriptions: list[tuple[Any, Any]] = []  # the waited on, but for the time sources' /clock
        self._clocks = []
        for node in self._nodes:
            for s in node.subscriptions:
                (self._clocks if _is_clock_of_time_source(s) else subscriptions).append((s, node))
        members: dict[str, Iterable[tuple[Any, Any]]] = {
            "subscription": subscriptions + self._clocks[:1],
            "timer": [(t, node) for node in self._nodes for t in node.timers],
            "service": [(s, node) for node in self._nodes for s in node.services],
            "client": [(c, node) for node in self._nodes for c in node.clients],
            "guard_condition": [(g, node) for node in self._nodes for g in node.guards] + [(self._wake, None)],
        }
        self._entities = {kind: {e.handle.pointer: (e, node) for e, node in pairs} for kind, pairs in members.items()}
        self._handles = {kind: [e.handle for e, _ in pairs] for kind, pairs in members.items()}
        waitables = [(w, node) for node in self._nodes for w in node.waitables]
        self._events = [(w, node) for w, node in waitables if isinstance(w, EventHandler)]
        self._waitables = [(w, node) for w, node in waitables if not isinstance(w, EventHandler)]
        count = NumberOfEntities(
            *(len(self._handles[kind]) for kind in ("subscription", "guard_condition", "timer", "client"))
        )
        for waitable, _ in self._waitables:
            count += waitable.get_num_entities()
        self._wait_set = _rclpy.WaitSet(
            count.num_subscriptions,
            count.num_guard_conditions,
            count.num_timers,
            count.num_clients,
            0,
            count.num_events,
            self._context.handle,
        )
        self._polled_wait_set = _rclpy.WaitSet(
            0, 0, 0, 0, len(self._handles["service"]), len(self._events), self._context.handle
        )


def _is_clock_of_time_source(subscription: Any) -> bool:
    """The /clock subscription rclpy's TimeSource makes for a node on sim time."""
    return getattr(subscription.callback, "__func__", None) is TimeSource.clock_callback


def _still_has(node: Any, entity: Any) -> bool:
    """`entity` is still one of `node`'s (rclpy drops an entity from these lists as it destroys it)."""
    if node is None:
        return False
    return any(
        entity in group
        for group in (node.subscriptions, node.timers, node.services, node.clients, node.guards, node.waitables)
    )


def _finish(result: Any) -> None:
    """A callback may be a coroutine function: run what it returned, which must not wait."""
    if not inspect.iscoroutine(result):
        return
    try:
        result.send(None)
    except StopIteration:
        return
    result.close()
    raise RuntimeError("a callback awaited something not yet done; BatchExecutor runs callbacks to completion")


def _call_timer(timer: Any) -> None:
    if not timer.handle.is_timer_ready():  # cancelled since the wait
        return
    timer.handle.call_timer()
    _finish(timer.callback())


def _call_subscription(subscription: Any) -> None:
    with_info = subscription._callback_type is not Subscription.CallbackType.MessageOnly
    while (taken := subscription.handle.take_message(subscription.msg_type, subscription.raw)) is not None:
        _finish(subscription.callback(*taken) if with_info else subscription.callback(taken[0]))


def _call_service(service: Any) -> None:
    while True:
        request, header = service.handle.service_take_request(service.srv_type.Request)
        if header is None:
            return
        response = service.callback(request, service.srv_type.Response())
        if inspect.iscoroutine(response):
            raise RuntimeError("an async service callback; BatchExecutor runs synchronous ones")
        service.send_response(response, header)


def _call_client(client: Any) -> None:
    header, response = client.handle.take_response(client.srv_type.Response)
    if header is None:
        return
    try:
        future = client.get_pending_request(header.request_id.sequence_number)
    except KeyError:  # the request was cancelled
        return
    future.set_result(response)


def _call_guard_condition(guard: Any) -> None:
    if guard.callback is not None:
        _finish(guard.callback())


def _call_waitable(waitable: Any) -> None:
    _finish(waitable.execute(waitable.take_data()))


_CALLS: dict[str, Callable[[Any], None]] = {
    "timer": _call_timer,
    "subscription": _call_subscription,
    "client": _call_client,
    "guard_condition": _call_guard_condition,
}
