"""The echo of a message a bridge brought in, so that it does not send it out again.

A topic that a template shares can be published and subscribed on several agents, so one bridge
both exports it (a local subscription) and imports it (a local publisher).  What it publishes,
its own subscription hears: sent out again, every message would circle the fleet for ever.
rclpy hands a raw subscription no publisher identity, so the bridge recognizes its echoes by
their bytes: each message brought in cancels one identical message heard within ECHO_SECONDS.
A local node publishing the very same bytes in that moment loses one copy to a remote twin that
arrived at the same time; every other message crosses once.
"""

from __future__ import annotations

import threading
import time
from collections import deque

ECHO_SECONDS = 2.0  # a bridge hears its own publication within milliseconds
MAX_PENDING = 10_000  # echoes waited for per topic: a bound, should the echoes never come


class Echoes:
    def __init__(self, seconds: float = ECHO_SECONDS) -> None:
        self.seconds = seconds
        self._pending: deque[tuple[float, bytes]] = deque(maxlen=MAX_PENDING)  # (when, bytes), oldest first
        self._lock = threading.Lock()  # brought in on a Zenoh thread, heard on the ROS thread

    def brought_in(self, data: bytes) -> None:
        """Call before publishing `data` locally."""
        with self._lock:
            self._pending.append((time.monotonic(), data))

    def is_echo(self, data: bytes) -> bool:
        """True (once per message brought in) when `data` is what this bridge published."""
        with self._lock:
            expired = time.monotonic() - self.seconds
            while self._pending and self._pending[0][0] < expired:
                self._pending.popleft()
            for index, (_, pending) in enumerate(self._pending):
                if pending == data:
                    del self._pending[index]
                    return True
        return False
