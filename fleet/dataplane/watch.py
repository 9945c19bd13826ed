"""What one agent's computer sees of a fleet's ROS graph: who publishes the topics its templates
share, and which nodes are up.

    python -m fleet.dataplane.watch CONFIG.json

CONFIG: {"fleet", "topics": [topic names], "nodes": bool, "status_file": path}.  One process per
fleet and agent whose robots share topics or run ROS nodes: a ROS node that is a discovery super
client (it learns every endpoint of the graph without subscribing, so it receives no
messages).  Every second it counts each topic's publishers, leaving out the fleet's Zenoh bridge (it
only republishes what came from another agent), and with "nodes" lists every node of the graph by
full name.  It writes {"wall_time", "started", "topics": {name: {"publishers", "silent"}}, "nodes":
[full names] (with "nodes")} to the status file, `silent` being the seconds since a publisher was
last seen (since the watch started, if never; null while there is one), `started` when it first
counted (wall time).  With the `dds` transport every watch sees the whole fleet's graph, with
`zenoh` its own computer's: `fleet status` combines the agents' (fleet.plan.view).  Exits 0 on
SIGTERM/SIGINT, 2 on a bad config.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

from fleet.rules import HELPER_ROS_ARGS, service_node_name

PERIOD = 1.0  # s between counts


def count_publishers(node, topic: str, bridge: str) -> int:
    return sum(1 for info in node.get_publishers_info_by_topic(topic) if info.node_name != bridge)


def node_names(node) -> set[str]:
    """Full names (`/robot1/controller`) of every node in the graph as this node sees it."""
    return {namespace.rstrip("/") + "/" + name for name, namespace in node.get_node_names_and_namespaces()}


def main(argv: list[str]) -> int:
    try:
        config = json.loads(Path(argv[0]).read_text())
        fleet, topics = str(config["fleet"]), [str(topic) for topic in config["topics"]]
        nodes = bool(config.get("nodes", False))
        status_file = Path(config["status_file"])
    except (IndexError, OSError, ValueError, KeyError, TypeError) as error:
        print(f"fleet watch: error: bad config: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from fleet.files import write_atomic
    from fleet.runtime.processes import stop_on_signals

    stop = stop_on_signals()
    rclpy.init(args=list(HELPER_ROS_ARGS), signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(service_node_name("watch", fleet))
    bridge = service_node_name("bridge", fleet)
    started, started_wall = time.monotonic(), time.time()
    last_seen: dict[str, float] = {}
    try:
        while True:
            now = time.monotonic()
            report = {}
            for topic in topics:
                publishers = count_publishers(node, topic, bridge)
                if publishers:
                    last_seen[topic] = now
                silent = None if publishers else round(now - last_seen.get(topic, started), 1)
                report[topic] = {"publishers": publishers, "silent": silent}
            status = {"wall_time": time.time(), "started": started_wall, "topics": report}
            if nodes:
                status["nodes"] = sorted(node_names(node))
            write_atomic(status_file, json.dumps(status))
            if stop.wait(PERIOD):
                break
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
