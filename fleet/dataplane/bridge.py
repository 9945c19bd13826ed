"""The `zenoh` transport: one bridge process per fleet and agent carries ROS topics between
this computer's DDS and the fleet's Zenoh network (same router, endpoints, TLS and access rules
as the control plane).

    python -m fleet.dataplane.bridge CONFIG.json

CONFIG: {"fleet", "connect": [endpoints], "zenoh_config": path or null, "exports": [TopicRoute],
"imports": [TopicRoute]}.  An export subscribes to a local topic with raw=True (rclpy hands over
the CDR bytes) and puts them on fleet/<fleet>/data/<topic>; an import subscribes to that key and
publishes the bytes on the local topic (rclpy's publish takes serialized bytes).  So any message
type crosses with no code of its own; the type name only creates the local endpoint.  Zenoh
delivers a put only where a subscriber is declared, so a topic travels only to agents that
import it.  Reliable topics block rather than drop when the link is congested; best-effort ones
drop.  The process exits 0 on SIGTERM/SIGINT, 2 on a bad config.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import logging
import sys
import threading
from pathlib import Path

log = logging.getLogger("fleet.bridge")
STATS_PERIOD = 10.0  # s between the bridge's traffic lines in its log


def message_class(type_name: str):
    """nav_msgs/msg/Odometry -> the class (generated code of the message package, imported by name)."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def ros_qos(route):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=route.depth,
        reliability=ReliabilityPolicy.RELIABLE if route.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if route.transient_local else DurabilityPolicy.VOLATILE,
    )


class Bridge:
    def __init__(self, fleet: str, exports, imports, session, node) -> None:
        import zenoh

        from fleet.wire.protocol import data_key

        self.counts = {"out": 0, "in": 0}
        self._keep = []  # Zenoh publishers and subscribers live as long as the bridge
        for route in exports:
            publisher = session.declare_publisher(
                data_key(fleet, route.name),
                congestion_control=zenoh.CongestionControl.BLOCK if route.reliable else zenoh.CongestionControl.DROP,
            )
            self._keep.append(publisher)
            node.create_subscription(
                message_class(route.type), route.name, self._sender(publisher), ros_qos(route), raw=True
            )
        for route in imports:
            publisher = node.create_publisher(message_class(route.type), route.name, ros_qos(route))
            self._keep.append(session.declare_subscriber(data_key(fleet, route.name), self._receiver(publisher)))

    def _sender(self, publisher):
        def send(data: bytes) -> None:  # rclpy executor thread
            publisher.put(data)
            self.counts["out"] += 1

        return send

    def _receiver(self, publisher):
        def receive(sample) -> None:  # Zenoh thread: publish and return
            publisher.publish(sample.payload.to_bytes())
            self.counts["in"] += 1

        return receive


def _spin(executor) -> None:
    from rclpy.executors import ExternalShutdownException

    with contextlib.suppress(ExternalShutdownException):
        executor.spin()


def main(argv: list[str]) -> int:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s fleet.bridge %(levelname)s %(message)s")
    from fleet.wire.protocol import BridgeRoutes
    from fleet.wire.session import AGENT_LEASE_MS, open_client_retrying

    try:
        config = json.loads(Path(argv[0]).read_text())
        routes = BridgeRoutes(exports=config["exports"], imports=config["imports"])
        fleet, connect = config["fleet"], list(config["connect"])
        zenoh_config = Path(config["zenoh_config"]) if config.get("zenoh_config") else None
    except (IndexError, OSError, ValueError, KeyError, TypeError) as error:
        print(f"fleet bridge: error: bad config: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from fleet.runtime.processes import stop_on_signals

    stop = stop_on_signals()
    rclpy.init(args=["--ros-args", "--disable-rosout-logs"], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(f"fleet_bridge_{fleet.replace('-', '_').replace('.', '_')}")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    session = open_client_retrying(connect, zenoh_config, AGENT_LEASE_MS, stop)
    try:
        if session is None:
            return 0
        bridge = Bridge(fleet, routes.exports, routes.imports, session, node)
        log.info(
            "bridge of fleet %s: %d topics out, %d in, through %s",
            fleet,
            len(routes.exports),
            len(routes.imports),
            ", ".join(connect),
        )
        # spin() handles every ready callback of one wait; a spin_once loop would rebuild the wait
        # set (hundreds of subscriptions) for each message.
        spinner = threading.Thread(target=_spin, args=(executor,), name="fleet-bridge-ros", daemon=True)
        spinner.start()
        # A line every 10 s while messages flow or stop flowing: what `fleet logs` cannot show.
        last = dict(bridge.counts)
        while not stop.wait(STATS_PERIOD):
            now = dict(bridge.counts)
            if now != last or any(last.values()):
                log.info(
                    "last %.0f s: %d messages out, %d in (routers: %d)",
                    STATS_PERIOD,
                    now["out"] - last["out"],
                    now["in"] - last["in"],
                    len(list(session.info.routers_zid())),
                )
            last = now
        log.info(
            "bridge of fleet %s stopping: %d messages out, %d in", fleet, bridge.counts["out"], bridge.counts["in"]
        )
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
        if session is not None:
            session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
