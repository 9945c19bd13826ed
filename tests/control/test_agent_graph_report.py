"""What an agent makes of its fleet watch's report of the ROS graph (fleet.server.agent)."""

from __future__ import annotations

import time

from fleet.server.agent import GRAPH_SETTLE, WATCH_FRESH, GraphReport, _graph_report, _seen_in_graph
from fleet.wire import protocol as p


def report(written_ago: float, watching_for: float, nodes: list[str]) -> dict:
    now = time.time()
    return {"wall_time": now - written_ago, "started": now - watching_for, "topics": {}, "nodes": nodes}


def test_a_fresh_report_names_the_nodes_and_whether_the_watch_has_settled():
    graph = _graph_report(report(0.5, GRAPH_SETTLE + 5, ["/r1/a", "/r1/b"]))
    assert graph is not None and graph.nodes == {"/r1/a", "/r1/b"} and graph.settled
    assert time.time() - graph.written > 0.4
    learning = _graph_report(report(0.5, GRAPH_SETTLE - 1, ["/r1/a"]))
    assert learning is not None and not learning.settled


def test_a_watch_gone_silent_or_not_watching_nodes_says_nothing():
    assert _graph_report(report(WATCH_FRESH + 1, 60, ["/r1/a"])) is None  # stuck or stopped
    assert _graph_report(None) is None  # nothing written yet
    assert _graph_report({"wall_time": time.time(), "started": 0.0, "topics": {}}) is None  # nodes not watched


def node(uptime: float) -> p.NodeState:
    return p.NodeState(name="a", fqn="/r1/a", state="running", uptime=uptime, ros=True)


def test_a_node_counts_as_in_the_graph_only_from_a_report_written_since_its_process_started():
    written = time.time() - 0.5
    settled = GraphReport(written, True, frozenset({"/r1/a"}))
    assert _seen_in_graph(node(uptime=10.0), settled) is True
    # Restarted 0.2 s ago: the report, older, may hold its previous process's entry.
    assert _seen_in_graph(node(uptime=0.2), settled) is False
    assert _seen_in_graph(node(uptime=10.0), GraphReport(written, True, frozenset({"/r1/b"}))) is False


def test_a_watch_still_learning_the_graph_names_what_it_found_and_is_silent_on_the_rest():
    # A new watch has not met every participant yet: a node it found is there, one it has not
    # found may be too (None, not False), so a robot is neither running nor said to lack it.
    learning = GraphReport(time.time() - 0.5, False, frozenset({"/r1/a"}))
    assert _seen_in_graph(node(uptime=10.0), learning) is True
    assert _seen_in_graph(p.NodeState(name="b", fqn="/r1/b", state="running", uptime=10.0, ros=True), learning) is None
