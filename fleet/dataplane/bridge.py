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
import it.  Every bridge probes its path through the router once a second (the router echoes
it) and opens a new session when a connected router has echoed nothing for ECHO_TIMEOUT.  The
process exits 0 on SIGTERM/SIGINT, 2 on a bad config.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import logging
import sys
import threading
import time
from pathlib import Path
from typing import Any

from fleet.dataplane.echoes import Echoes

log = logging.getLogger("fleet.bridge")
STATS_PERIOD = 10.0  # s between the bridge's traffic lines in its log
PROBE_PERIOD = 1.0  # s between probes of the path through the router
ECHO_TIMEOUT = 5.0  # s without an echo, while a router is connected, before the session is replaced


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
    """The ROS side is made once; the Zenoh side can be made again on a new session (attach),
    when the router stops echoing this bridge's probe (see main)."""

    def __init__(self, fleet: str, agent: str, exports, imports, node) -> None:
        self.fleet, self.agent = fleet, agent
        self.exports, self.imports = list(exports), list(imports)
        self.counts = {"out": 0, "in": 0}
        self.last_echo = 0.0  # time.monotonic() of the router's last echo of our probe
        self._zenoh: dict[str, Any] = {}  # exported topic -> its Zenoh publisher on the current session
        self._keep: list[Any] = []  # the current session's subscribers and publishers
        # Topics both sent and brought in (shared by templates): what we publish we hear again.
        both = {route.name for route in self.exports} & {route.name for route in self.imports}
        self._echoes = {name: Echoes() for name in both}
        self._ros_publishers = {
            route.name: node.create_publisher(message_class(route.type), route.name, ros_qos(route))
            for route in self.imports
        }
        for route in self.exports:
            node.create_subscription(
                message_class(route.type), route.name, self._sender(route.name), ros_qos(route), raw=True
            )

    def attach(self, session) -> None:
        """Declare the Zenoh side on `session` (replacing what an earlier session had)."""
        import zenoh

        from fleet.wire.protocol import data_key, echo_keys

        publishers = {}
        keep: list[Any] = []
        for route in self.exports:
            # DROP, as rmw_zenoh does for every KEEP_LAST topic (all of ours): with BLOCK, one agent
            # whose link was cut filled the router's queue towards it and stalled every bridge's
            # traffic, the other agents' too, until the router gave up on that link.
            publishers[route.name] = session.declare_publisher(
                data_key(self.fleet, route.name),
                congestion_control=zenoh.CongestionControl.DROP,
                allowed_destination=zenoh.Locality.REMOTE,  # not to our own import of a shared topic
            )
        for route in self.imports:
            keep.append(session.declare_subscriber(data_key(self.fleet, route.name), self._receiver(route.name)))
        ping, pong = echo_keys(self.fleet, self.agent)
        keep.append(session.declare_subscriber(pong, self._echoed))
        self._ping = session.declare_publisher(ping)
        self._zenoh, self._keep = publishers, [*keep, *publishers.values(), self._ping]
        self.last_echo = time.monotonic()  # the new session gets its full grace period

    def probe(self) -> None:
        with contextlib.suppress(Exception):  # a closed session: the next attach replaces it
            self._ping.put(b"?")

    def _echoed(self, sample) -> None:
        self.last_echo = time.monotonic()

    def _sender(self, topic: str):
        echoes = self._echoes.get(topic)

        def send(data: bytes) -> None:  # rclpy executor thread
            publisher = self._zenoh.get(topic)
            if publisher is None or (echoes is not None and echoes.is_echo(data)):
                return
            try:
                publisher.put(data)
            except Exception:  # the session is being replaced: this message is lost, as on a cut link
                return
            self.counts["out"] += 1

        return send

    def _receiver(self, topic: str):
        publisher = self._ros_publishers[topic]
        echoes = self._echoes.get(topic)

        def receive(sample) -> None:  # Zenoh thread: publish and return
            data = sample.payload.to_bytes()
            if echoes is not None:
                echoes.brought_in(data)
            publisher.publish(data)
            self.counts["in"] += 1

        return receive


def _replace_session(session, bridge: Bridge, connect: list[str], zenoh_config: Path | None, stop: threading.Event):
    """A new session for a connected one that the router no longer echoes (seen after a link to
    the router dropped and came back: Zenoh reconnected, but nothing reached this bridge)."""
    from fleet.wire.session import AGENT_LEASE_MS, open_client_retrying

    log.warning("the router has not echoed this bridge for %.0f s: opening a new Zenoh session", ECHO_TIMEOUT)
    with contextlib.suppress(Exception):  # a broken session may not close cleanly: drop it anyway
        session.close()
    session = open_client_retrying(connect, zenoh_config, AGENT_LEASE_MS, stop)
    if session is not None:
        bridge.attach(session)
    return session


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
        fleet, agent, connect = config["fleet"], config["agent"], list(config["connect"])
        zenoh_config = Path(config["zenoh_config"]) if config.get("zenoh_config") else None
    except (IndexError, OSError, ValueError, KeyError, TypeError) as error:
        print(f"fleet bridge: error: bad config: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from fleet.rules import service_node_name
    from fleet.runtime.processes import stop_on_signals

    stop = stop_on_signals()
    rclpy.init(args=["--ros-args", "--disable-rosout-logs"], signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(service_node_name("bridge", fleet))
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    session = open_client_retrying(connect, zenoh_config, AGENT_LEASE_MS, stop)
    try:
        if session is None:
            return 0
        bridge = Bridge(fleet, agent, routes.exports, routes.imports, node)
        bridge.attach(session)
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
        last, next_stats = dict(bridge.counts), time.monotonic() + STATS_PERIOD
        while not stop.wait(PROBE_PERIOD):
            bridge.probe()
            routers = len(list(session.info.routers_zid()))
            if routers and time.monotonic() - bridge.last_echo > ECHO_TIMEOUT:
                session = _replace_session(session, bridge, connect, zenoh_config, stop)
                if session is None:
                    break
            if time.monotonic() >= next_stats:
                now, next_stats = dict(bridge.counts), next_stats + STATS_PERIOD
                if now != last or any(last.values()):
                    log.info(
                        "last %.0f s: %d messages out, %d in (routers: %d)",
                        STATS_PERIOD,
                        now["out"] - last["out"],
                        now["in"] - last["in"],
                        routers,
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
