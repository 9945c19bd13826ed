"""What an agent answers to `fleet logs`: log files read and grouped (files only, no processes)."""

from __future__ import annotations

from fleet.server.logs import read_log, robot_logs
from fleet.wire import protocol as p

LOGGERS = {"controller": "r1.controller", "battery": "r1.battery", "safety": "r1.safety"}


def test_read_log_tails_then_follows_whole_lines(tmp_path):
    path = tmp_path / "node.log"
    path.write_text("".join(f"line {i}\n" for i in range(100)))
    lines, offset = read_log(path, 3, None)
    assert lines == ["line 97", "line 98", "line 99"]
    with open(path, "a") as stream:
        stream.write("line 100\nhalf")
    lines, offset = read_log(path, 3, offset)
    assert lines == ["line 100"]
    with open(path, "a") as stream:
        stream.write(" done\n")
    assert read_log(path, 3, offset)[0] == ["half done"]
    assert read_log(tmp_path / "missing.log", 3, None) == ([], 0)


def test_nodes_sharing_a_process_get_its_lines_once(tmp_path):
    # isolation: robot runs controller and battery in one process (one log); safety runs alone.
    composite, alone = tmp_path / "composite-1.log", tmp_path / "safety-1.log"
    composite.write_text("[WARN] [r1.controller]: blocked\n[INFO] [r1.battery]: 80%\n")
    alone.write_text("[INFO] [r1.safety]: clear\n")
    files = {"controller": composite, "battery": composite, "safety": alone}
    request = p.LogsRequest(fleet="f", robot="r1", tail=10)

    reply = robot_logs(["controller", "battery", "safety"], files.get, request, LOGGERS)

    assert [(line.node, line.text) for line in reply.lines] == [
        ("controller+battery", "[WARN] [r1.controller]: blocked"),
        ("controller+battery", "[INFO] [r1.battery]: 80%"),
        ("safety", "[INFO] [r1.safety]: clear"),
    ]
    # Following: each node's cursor is its file's offset, and only new lines come next time.
    with open(composite, "a") as stream:
        stream.write("[INFO] [r1.battery]: 79%\n")
    request = p.LogsRequest(fleet="f", robot="r1", tail=10, cursor=reply.cursor)
    again = robot_logs(["controller", "battery", "safety"], files.get, request, LOGGERS)
    assert [(line.node, line.text) for line in again.lines] == [("controller+battery", "[INFO] [r1.battery]: 79%")]


def test_one_node_of_a_shared_process_gets_the_lines_of_its_own_logger(tmp_path):
    """`fleet logs r1 controller` of isolation: robot: the controller's lines (and the traceback
    after one), not its neighbours', and as many as --tail asks for."""
    composite = tmp_path / "composite-1.log"
    composite.write_text(
        "[INFO] [1.0] [r1.controller]: driving\n"
        "[INFO] [1.1] [r1.battery]: 80%\n"
        "[ERROR] [1.2] [r1.controller]: boom\n"
        "Traceback (most recent call last):\n" + "".join(f"[INFO] [2.{i}] [r1.battery]: 79%\n" for i in range(8))
    )
    files = {"controller": composite, "battery": composite}
    request = p.LogsRequest(fleet="f", robot="r1", node="controller", tail=2)
    reply = robot_logs(["controller", "battery"], files.get, request, LOGGERS)
    assert [(line.node, line.text) for line in reply.lines] == [
        ("controller", "[ERROR] [1.2] [r1.controller]: boom"),
        ("controller", "Traceback (most recent call last):"),
    ]
    # Followed: only the controller's new lines.
    with open(composite, "a") as stream:
        stream.write("[INFO] [3.0] [r1.battery]: 78%\n[INFO] [3.1] [r1.controller]: arrived\n")
    request = p.LogsRequest(fleet="f", robot="r1", node="controller", tail=2, cursor=reply.cursor)
    again = robot_logs(["controller", "battery"], files.get, request, LOGGERS)
    assert [line.text for line in again.lines] == ["[INFO] [3.1] [r1.controller]: arrived"]


def test_a_shared_log_in_a_format_without_loggers_is_shown_whole(tmp_path):
    composite = tmp_path / "composite-1.log"
    composite.write_text("tick\ntock\n")
    request = p.LogsRequest(fleet="f", robot="r1", node="battery", tail=10)
    reply = robot_logs(["controller", "battery"], {"controller": composite, "battery": composite}.get, request, LOGGERS)
    assert [(line.node, line.text) for line in reply.lines] == [("battery", "tick"), ("battery", "tock")]
