"""Per-process output: a rotating log file, the last lines in memory, and an optional echo."""

from __future__ import annotations

import collections
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import IO

MAX_BYTES = 5 * 1024 * 1024
BACKUPS = 3
TAIL_LINES = 1000


class RotatingLog:
    """Appends lines to `path`; past `max_bytes` it shifts path -> path.1 -> ... -> path.N."""

    def __init__(self, path: Path, max_bytes: int = MAX_BYTES, backups: int = BACKUPS):
        self.path = Path(path)
        self.max_bytes = max_bytes
        self.backups = backups
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._file = open(self.path, "a", encoding="utf-8", errors="replace")  # noqa: SIM115 (the log stays open)
        self._size = self._file.tell()

    def write(self, line: str) -> None:
        data = line + "\n"
        if self._size + len(data) > self.max_bytes and self._size > 0:
            self._rotate()
        self._file.write(data)
        self._file.flush()
        self._size += len(data)

    def _rotate(self) -> None:
        self._file.close()
        for index in range(self.backups - 1, 0, -1):
            older = self.path.with_name(f"{self.path.name}.{index}")
            if older.exists():
                os.replace(older, self.path.with_name(f"{self.path.name}.{index + 1}"))
        if self.backups > 0:
            os.replace(self.path, self.path.with_name(f"{self.path.name}.1"))
        else:
            self.path.unlink(missing_ok=True)
        self._file = open(self.path, "a", encoding="utf-8", errors="replace")  # noqa: SIM115 (the log stays open)
        self._size = 0

    def close(self) -> None:
        self._file.close()


class ProcessOutput:
    """Everything one supervised process (all its incarnations) printed."""

    def __init__(self, path: Path, echo: Callable[[str], None] | None = None):
        self.log = RotatingLog(path)
        self.echo = echo
        self._tail: collections.deque[str] = collections.deque(maxlen=TAIL_LINES)
        self._lock = threading.Lock()
        self._closed = False

    def add(self, line: str) -> None:
        with self._lock:
            self._tail.append(line)
            if not self._closed:
                self.log.write(line)
        if self.echo is not None:
            self.echo(line)

    def tail(self, count: int) -> list[str]:
        with self._lock:
            lines = list(self._tail)
        return lines[-count:] if count > 0 else []

    def follow(self, stream: IO[bytes]) -> threading.Thread:
        """Read `stream` line by line on a daemon thread until it closes."""
        thread = threading.Thread(
            target=self._pump, args=(stream,), daemon=True, name=f"fleet-log-{self.log.path.stem}"
        )
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
