"""Taking the serialized messages of many subscriptions at once, without an executor.

rclpy's executor runs one Python callback per message and rebuilds its wait set for each: at
thousands of messages a second over hundreds of subscriptions, that cost more CPU than the
messages.  A RawTaker waits on all its subscriptions (made with raw=True) in one wait set and
takes everything that has arrived, as CDR bytes.  It uses rclpy's own wait set and take, the
calls the executor makes underneath.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from typing import Any, Generic, TypeVar

Tag = TypeVar("Tag")  # what the caller names each subscription by


class RawTaker(Generic[Tag]):
    """`with RawTaker(node, [(subscription, tag), ...]) as taker: taker.take(timeout_ns)` ->
    [(tag, CDR bytes), ...] of every message waiting, in arrival order per subscription."""

    def __init__(self, node, subscriptions: Sequence[tuple[Any, Tag]]) -> None:
        self._context = node.context
        self._subscriptions = list(subscriptions)
        self._in_use = contextlib.ExitStack()
        self._wait_set: Any = None
        self._by_pointer: dict[int, tuple[Any, Any, Tag]] = {}

    def __enter__(self) -> RawTaker[Tag]:
        from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy

        # rclpy's handles must stay valid (not destroyed under us) while they are waited on.
        for subscription, _ in self._subscriptions:
            self._in_use.enter_context(subscription.handle)
        self._in_use.enter_context(self._context.handle)
        self._wait_set = _rclpy.WaitSet(len(self._subscriptions), 0, 0, 0, 0, 0, self._context.handle)
        self._by_pointer = {s.handle.pointer: (s.handle, s.msg_type, tag) for s, tag in self._subscriptions}
        return self

    def __exit__(self, *_exc) -> None:
        self._in_use.close()

    def ok(self) -> bool:
        """False once rclpy is shut down."""
        return self._context.ok()

    def take(self, timeout_ns: int) -> list[tuple[Tag, bytes]]:
        """Wait up to `timeout_ns` for a message, then take every one that has arrived."""
        self._wait_set.clear_entities()
        for subscription, _ in self._subscriptions:
            self._wait_set.add_subscription(subscription.handle)
        self._wait_set.wait(timeout_ns)
        taken: list[tuple[Tag, bytes]] = []
        for pointer in self._wait_set.get_ready_entities("subscription"):
            handle, kind, tag = self._by_pointer[pointer]
            while (message := handle.take_message(kind, True)) is not None:
                taken.append((tag, message[0]))
        return taken
