"""What an agent answers to `fleet logs`: log files read and grouped (files only, no processes)."""

from __future__ import annotations

from fleet.server.logs import read_log, robot_logs
from fleet.wire import protocol as p


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

    reply = robot_logs(["controller", "battery", "safety"], files.get, request)

    assert [(line.node, line.text) for line in reply.lines] == [
        ("controller+battery", "[WARN] [r1.controller]: blocked"),
        ("controller+battery", "[INFO] [r1.battery]: 80%"),
        ("safety", "[INFO] [r1.safety]: clear"),
    ]
    # Following: each node's cursor is its file's offset, and only new lines come next time.
    with open(composite, "a") as stream:
        stream.write("[INFO] [r1.battery]: 79%\n")
    request = p.LogsRequest(fleet="f", robot="r1", tail=10, cursor=reply.cursor)
    again = robot_logs(["controller", "battery", "safety"], files.get, request)
    assert [(line.node, line.text) for line in again.lines] == [("controller+battery", "[INFO] [r1.battery]: 79%")]


def test_one_node_of_a_shared_process_is_labelled_with_its_own_name(tmp_path):
    composite = tmp_path / "composite-1.log"
    composite.write_text("tick\n")
    request = p.LogsRequest(fleet="f", robot="r1", node="battery", tail=10)
    reply = robot_logs(["battery"], {"battery": composite}.get, request)
    assert [(line.node, line.text) for line in reply.lines] == [("battery", "tick")]
