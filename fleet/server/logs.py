"""A robot's log lines as its agent serves them to `fleet logs` and the dashboard."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

from fleet.runtime.node_log import lines_of
from fleet.wire import protocol as p

SHARED_SCAN = 10  # a node's last N lines are looked for in the last N * 10 * (nodes sharing it) lines


def robot_logs(
    nodes: list[str], log_file: Callable[[str], Path | None], request: p.LogsRequest, loggers: Mapping[str, str]
) -> p.LogsReply:
    """The lines of the logs of the robot's `nodes` (every node of it), or of `request.node`'s
    alone, each log file read once.  `loggers`: each node's rcutils logger name.

    Nodes that share a process (`isolation: robot` composes a robot's nodes into one) share its
    log file: its lines are sent once, labelled with every node it hosts (`controller+battery`),
    not once per node.  One node of them asked for alone gets the lines its own logger printed
    (fleet.runtime.node_log.lines_of), as `ros2 launch` users read a node's output by its
    logger.  The cursor keeps an offset per node, so a client following the log sends back what
    it got, whatever the grouping.

    A follower's place is kept in the nodes its cursor names that the robot does not run now
    (`fleet restart` stops them all for a moment): they get no lines and their offsets back, and
    the lines written meanwhile (how each process ended, the new one's start) come once they run
    again, rather than the follower losing them or being told the node does not exist.
    """
    kept = {node: offset for node, offset in (request.cursor or {}).items() if node not in nodes}
    if request.node in kept:
        return p.LogsReply(lines=[], cursor=kept)
    groups: dict[Path | None, list[str]] = {}
    for node in nodes:
        groups.setdefault(log_file(node), []).append(node)
    shared_by = 1
    if request.node:
        path = log_file(request.node)
        shared_by = len(groups.get(path, ()))
        groups = {path: [request.node]}
    lines: list[p.LogLine] = []
    cursor: dict[str, int] = {}
    for path, members in groups.items():
        start = (request.cursor or {}).get(members[0])
        own_logger = loggers.get(members[0]) if shared_by > 1 else None
        # a shared log holds the others' lines too: look further back to find `tail` of its own
        scan = SHARED_SCAN * shared_by if own_logger else 1
        text_lines, offset = read_log(path, request.tail * scan, start)
        if own_logger:
            own = lines_of(text_lines, own_logger)
            if own is not None:
                text_lines = own
            if start is None:  # a tail: of the node's own lines
                text_lines = text_lines[-request.tail :] if request.tail else []
        cursor.update(dict.fromkeys(members, offset))
        label = "+".join(members)
        lines.extend(p.LogLine(node=label, text=text) for text in text_lines)
    return p.LogsReply(lines=lines, cursor={**kept, **cursor})


def read_log(path: Path | None, tail: int, start: int | None) -> tuple[list[str], int]:
    """Lines of a log file: the last `tail` ones (start None) or those after byte offset `start`."""
    if path is None or not path.exists():
        return [], 0
    size = path.stat().st_size
    with open(path, "rb") as stream:
        if start is None or start > size:  # first read, or the file was rotated
            stream.seek(max(0, size - 256 * max(tail, 1)))
            data = stream.read()
            lines = data.decode("utf-8", "replace").splitlines()
            if stream.tell() > len(data) and lines:  # first line may be cut
                lines = lines[1:]
            return lines[-tail:] if tail else [], size
        stream.seek(start)
        data = stream.read(size - start)
    complete = data.rfind(b"\n") + 1  # only whole lines; the rest comes next time
    return data[:complete].decode("utf-8", "replace").splitlines(), start + complete
