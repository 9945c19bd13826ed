"""Per-process output: a rotating log file, the last lines in memory, and an optional echo."""

from __future__ import annotations

import collections
import logging
import threading
from collections.abc import Callable
from logging.handlers import RotatingFileHandler
from pathlib import Path
from typing import IO

MAX_BYTES = 5 * 1024 * 1024
BACKUPS = 3
TAIL_LINES = 1000


def rotating_file(path: Path, max_bytes: int = MAX_BYTES, backups: int = BACKUPS) -> RotatingFileHandler:
    """A log file that, past `max_bytes`, shifts path -> path.1 -> ... -> path.N."""
    path.parent.mkdir(parents=True, exist_ok=True)
    handler = RotatingFileHandler(path, maxBytes=max_bytes, backupCount=backups, encoding="utf-8", errors="replace")
    handler.setFormatter(logging.Formatter("%(message)s"))
    return handler


class ProcessOutput:
    """Everything one supervised process (all its incarnations) printed."""

    def __init__(self, path: Path, echo: Callable[[str], None] | None = None):
        self.path = Path(path)
        self.log = rotating_file(self.path)
        self.echo = echo
        self._tail: collections.deque[str] = collections.deque(maxlen=TAIL_LINES)
        self._lock = threading.Lock()
        self._closed = False

    def add(self, line: str) -> None:
        with self._lock:
            self._tail.append(line)
            if not self._closed:
                self.log.emit(logging.makeLogRecord({"msg": line}))
        if self.echo is not None:
            self.echo(line)

    def tail(self, count: int) -> list[str]:
        with self._lock:
            lines = list(self._tail)
        return lines[-count:] if count > 0 else []

    def follow(self, stream: IO[bytes]) -> threading.Thread:
        """Read `stream` line by line on a daemon thread until it closes."""
        thread = threading.Thread(target=self._pump, args=(stream,), daemon=True, name=f"fleet-log-{self.path.stem}")
        thread.start()
        return thread

    def _pump(self, stream: IO[bytes]) -> None:
        with stream:
            for raw in iter(stream.readline, b""):
                self.add(raw.decode("utf-8", errors="replace").rstrip("\r\n"))

    def close(self) -> None:
        with self._lock:
            self._closed = True
            self.log.close()
