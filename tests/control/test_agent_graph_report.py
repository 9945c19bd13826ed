"""What an agent makes of its fleet watch's report of the ROS graph (fleet.server.agent)."""

from __future__ import annotations

import time

from fleet.server.agent import GRAPH_SETTLE, WATCH_FRESH, _graph_nodes, _seen_in_graph
from fleet.wire import protocol as p


def report(written_ago: float, watching_for: float, nodes: list[str]) -> dict:
    now = time.time()
    return {"wall_time": now - written_ago, "started": now - watching_for, "topics": {}, "nodes": nodes}


def test_a_fresh_report_of_a_settled_watch_names_the_nodes():
    written, nodes = _graph_nodes(report(0.5, GRAPH_SETTLE + 5, ["/r1/a", "/r1/b"])) or (0.0, set())
    assert nodes == {"/r1/a", "/r1/b"} and time.time() - written > 0.4


def test_a_watch_still_learning_the_graph_or_gone_silent_says_nothing():
    assert _graph_nodes(report(0.5, GRAPH_SETTLE - 1, ["/r1/a"])) is None  # every node would look absent
    assert _graph_nodes(report(WATCH_FRESH + 1, 60, ["/r1/a"])) is None  # stuck or stopped
    assert _graph_nodes(None) is None  # nothing written yet
    assert _graph_nodes({"wall_time": time.time(), "started": 0.0, "topics": {}}) is None  # nodes not watched


def node(uptime: float) -> p.NodeState:
    return p.NodeState(name="a", fqn="/r1/a", state="running", uptime=uptime, ros=True)


def test_a_node_counts_as_in_the_graph_only_from_a_report_written_since_its_process_started():
    written = time.time() - 0.5
    assert _seen_in_graph(node(uptime=10.0), written, {"/r1/a"})
    # Restarted 0.2 s ago: the report, older, may hold its previous process's entry.
    assert not _seen_in_graph(node(uptime=0.2), written, {"/r1/a"})
    assert not _seen_in_graph(node(uptime=10.0), written, {"/r1/b"})
