"""Per-process output: a rotating log file, the last lines in memory, and an optional echo; and
which node printed a line of a process that several nodes share.

rcutils prints each line with the node's logger name, its fully qualified name with dots
(`/robot1/controller` logs as `robot1.controller`); the lines that follow without such a prefix
(a traceback) belong to the same logger.
"""

from __future__ import annotations

import collections
import logging
import re
import threading
import time
from collections.abc import Callable, Iterable
from logging.handlers import RotatingFileHandler
from pathlib import Path
from typing import IO

MAX_BYTES = 5 * 1024 * 1024
BACKUPS = 3
TAIL_LINES = 1000
LOG_FORMAT = "[{severity}] [{time}] [{name}]: {message}"  # the rcutils default, fixed where fleet splits
LOG_LINE = re.compile(r"^\[[A-Z]+\] \[[0-9.]+\] \[([^\]]+)\]: ")
# rcl also writes every process's log to a file of its own, one new file per process start, and
# never removes one (a node in a crash loop adds one per respawn): the newest few are kept.
RCL_LOG_FILES_KEPT = 20


def rcl_log_dir(log_dir: Path) -> Path:
    """Where rcl's own log files of the processes logging to `log_dir` go (their ROS_LOG_DIR):
    beside fleet's logs, not piled up in ~/.ros/log."""
    return log_dir / "ros"


def prune_rcl_logs(log_dir: Path, keep: int = RCL_LOG_FILES_KEPT) -> None:
    """Remove all but the `keep` most recently written of rcl's log files under `log_dir`; call
    before a process starts.  A quiet process's file may go while it runs: it keeps writing to
    it unseen, and its lines are in fleet's own log of it all the same."""
    try:
        files = [path for path in rcl_log_dir(log_dir).iterdir() if path.is_file()]
    except OSError:  # none yet
        return
    if len(files) <= keep:
        return
    files.sort(key=_written_at, reverse=True)
    for path in files[keep:]:
        path.unlink(missing_ok=True)


def _written_at(path: Path) -> float:
    try:
        return path.stat().st_mtime
    except OSError:  # gone meanwhile
        return 0.0


def logger_name(fqn: str) -> str:
    """The rcutils logger of a node: `/robot1/controller` -> `robot1.controller`."""
    return fqn.strip("/").replace("/", ".")


def launch_line(process: str, severity: str, message: str) -> str:
    """A line the launch session writes into a process's log about the process itself (started,
    ended), as `ros2 launch` reports its processes: under the process's name (`controller-1`),
    in the rcutils layout so that it parses like the nodes' own lines."""
    return LOG_FORMAT.format(severity=severity, time=f"{time.time():.9f}", name=process, message=message)


def is_launch_logger(logger: str) -> bool:
    """Whether a line's logger is a process's (launch_line), not a node's: a process name holds
    a dash (`controller-1`), which no ROS name can."""
    return "-" in logger


def logger_of(line: str) -> str | None:
    """The logger that printed `line`, None for a line without one (it continues the one before)."""
    match = LOG_LINE.match(line)
    return match.group(1) if match else None


def routine(line: str) -> bool:
    """Whether `line` is a node's routine log line (INFO or DEBUG), which says nothing of why its
    process ended: a WARN or ERROR, or a line outside the log format (a traceback, argparse's
    complaint), may."""
    return LOG_LINE.match(line) is not None and line.startswith(("[INFO]", "[DEBUG]"))


def belongs_to(logger: str, node_logger: str) -> bool:
    """A node's own logger and its child loggers (`robot1.controller.planner`) are the node's."""
    return logger == node_logger or logger.startswith(node_logger + ".")


def lines_of(lines: Iterable[str], node_logger: str) -> list[str] | None:
    """The lines of `lines` that the node of `node_logger` printed, and the launch session's lines
    about their process (it started, it ended: every node of it); None when no node's line names
    a logger at all (a console format of the user's own), so they cannot be told apart."""
    kept: list[str] = []
    named = mine = False
    for line in lines:
        logger = logger_of(line)
        if logger is not None and is_launch_logger(logger):  # about the process: every node's
            kept.append(line)
            mine = False
            continue
        if logger is not None:
            named, mine = True, belongs_to(logger, node_logger)
        if mine:
            kept.append(line)
    return kept if named else None


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

    def add(self, line: str, echo: bool = True) -> None:
        with self._lock:
            self._tail.append(line)
            if not self._closed:
                self.log.emit(logging.makeLogRecord({"msg": line}))
        if echo and self.echo is not None:
            try:
                self.echo(line)
            except OSError:  # the screen went away (`fleet run ... | head`): the log goes on
                self.echo = None

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
