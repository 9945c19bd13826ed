"""The `zenoh` transport: one bridge process per fleet and agent carries ROS topics between
this computer's DDS and the fleet's Zenoh network (same router, endpoints, TLS and access rules
as the control plane).

    python -m fleet.dataplane.bridge CONFIG.json

CONFIG: {"fleet", "agent", "connect": [endpoints], "zenoh_config": path or null, "exports":
[TopicRoute], "imports": [TopicRoute]}.

Imports: for each topic it brings in, a bridge declares a liveliness token (protocol
import_token_key) and publishes on the local topic, with the route's QoS, the serialized messages
of the batches put on its agent's batch key.  Exports: a bridge subscribes to its local topics
with raw=True (rclpy hands over the CDR bytes), learns from the tokens which agents bring in each
topic, and sends every agent one batch (fleet.dataplane.batch) of whatever its topics received
since the last wake-up: one Zenoh put for many messages, and no put at all for a topic no agent
brings in.  Any message type crosses with no code of its own: the type name only creates the
local endpoint.  A latched (transient local) topic's last `depth` messages are sent again to an
agent whose token appears, as DDS does for a late subscriber.  A topic a bridge both exports and
imports (one its templates share) would come back to it: what the importer publishes, the
exporter's subscription hears, and it is not sent again (fleet.dataplane.echoes).

Every bridge probes its path through the router once a second (the router echoes it) and opens
a new session when a connected router has echoed nothing for ECHO_TIMEOUT.  The process exits 0
on SIGTERM/SIGINT, 2 on a bad config.
"""

from __future__ import annotations

import collections
import contextlib
import importlib
import json
import logging
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Any

from fleet.dataplane.batch import BatchError, batches, messages, record
from fleet.dataplane.echoes import Echoes
from fleet.dataplane.take import RawTaker

log = logging.getLogger("fleet.bridge")
STATS_PERIOD = 10.0  # s between the bridge's traffic lines in its log
PROBE_PERIOD = 1.0  # s between probes of the path through the router
ECHO_TIMEOUT = 5.0  # s without an echo, while a router is connected, before the session is replaced
TOKENS_TIMEOUT = 5.0  # s to learn the importers already there when a session opens
# The exporting side's own DDS queue per topic: it only has to hold what arrives between two
# wake-ups of the exporter; the publisher's depth (what its subscribers see) is the route's.
EXPORT_DEPTH = 100
WAKE_PERIOD_NS = 100_000_000  # the exporter's longest wait, to notice a stop and pending resends
# After a wake-up that found a burst (BURST messages or more), the exporter lets the next ones
# gather for LINGER s: under load a wake-up and a put per few messages cost more CPU than the
# messages; a lone robot's messages (one or two per wake-up) go at once.
BURST, LINGER = 8, 0.005
IMPORT_QUEUE = 1000  # batches received and not yet published (seconds of a fleet's traffic)
# Every put uses Zenoh's `drop` congestion control, as rmw_zenoh does for KEEP_LAST topics: with
# `block`, one agent whose link was cut filled the router's queue towards it and stalled every
# bridge's traffic, the other agents' too, until the router gave up on that link.  A put waits
# this long (µs) for room in a full queue before it is dropped (Zenoh's default: 1 ms, which a
# busy computer's scheduler exceeds): momentary congestion delays messages instead of losing them,
# a dead link costs each put this wait at most.
WAIT_BEFORE_DROP_US = 50_000
# Batches of 64 KiB queued towards the router (Zenoh's default: 2): room for a burst of a fleet's
# traffic while this process or its link is briefly behind.
QUEUE_BATCHES = 16
SESSION_SETTINGS = {
    "transport/link/tx/queue/congestion_control/drop/wait_before_drop": WAIT_BEFORE_DROP_US,
    "transport/link/tx/queue/size/data": QUEUE_BATCHES,
}


def message_class(type_name: str):
    """nav_msgs/msg/Odometry -> the class (generated code of the message package, imported by name)."""
    package, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def ros_qos(route, depth: int | None = None):
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        depth=depth or route.depth,
        reliability=ReliabilityPolicy.RELIABLE if route.reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if route.transient_local else DurabilityPolicy.VOLATILE,
    )


class Exporter:
    """Local topics -> batches for the agents that bring them in.  Its own thread takes the
    messages straight from the subscriptions (fleet.dataplane.take, no executor)."""

    def __init__(self, fleet: str, agent: str, routes, node, echoes: dict[str, Echoes]) -> None:
        self.fleet, self.agent, self.node = fleet, agent, node
        self._echoes = echoes  # topic -> what the importer published of it, not to be sent back
        self.sent = 0  # messages put (a message for two agents counts twice)
        self.puts = 0
        self._session: Any = None
        self._publishers: dict[str, Any] = {}  # agent -> the current session's publisher of its batches
        self._lock = threading.Lock()
        self._importers: dict[str, set[str]] = {}  # topic -> agents that bring it in
        self._resend: list[tuple[str, str]] = []  # (agent, latched topic) whose token just appeared
        self._latched: dict[str, collections.deque[bytes]] = {
            r.name: collections.deque(maxlen=r.depth) for r in routes if r.transient_local
        }
        self._subscriptions = [
            (
                node.create_subscription(
                    message_class(r.type), r.name, lambda _: None, ros_qos(r, max(r.depth, EXPORT_DEPTH)), raw=True
                ),
                r.name.encode(),
            )
            for r in routes
        ]
        self._thread = threading.Thread(target=self._run, name="fleet-bridge-export", daemon=True)
        self._stop = threading.Event()

    def attach(self, session) -> list[Any]:
        """Learn the importers anew from `session` (their tokens come again: history)."""
        from fleet.wire.protocol import import_token_key

        with self._lock:
            self._importers, self._session, self._publishers = {}, session, {}
        pattern = import_token_key(self.fleet, "*", "**")
        keep = [session.liveliness().declare_subscriber(pattern, self._on_token, history=True)]
        # The history comes later, on Zenoh's thread: ask for the tokens already there too, so
        # that the first messages taken are not dropped for want of an importer it will know of.
        for reply in session.liveliness().get(pattern, timeout=TOKENS_TIMEOUT):
            if reply.ok is not None:
                self._on_token(reply.ok)
        return keep

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():  # never started when no router was reached before the stop
            self._thread.join(timeout=5.0)

    def _on_token(self, sample) -> None:  # Zenoh thread
        import zenoh

        from fleet.wire.protocol import imported_topic

        found = imported_topic(self.fleet, sample.key_expr)
        if found is None or found[0] == self.agent:  # our own imports: they are already local
            return
        agent, topic = found
        with self._lock:
            agents = self._importers.setdefault(topic, set())
            if sample.kind == zenoh.SampleKind.DELETE:
                agents.discard(agent)
            elif agent not in agents:  # the same token from the history and the get: once
                agents.add(agent)
                if topic in self._latched:
                    self._resend.append((agent, topic))

    def _run(self) -> None:
        with RawTaker(self.node, self._subscriptions) as taker:
            while not self._stop.is_set() and taker.ok():
                taken = taker.take(WAKE_PERIOD_NS)
                self._send(taken)
                if len(taken) >= BURST:
                    time.sleep(LINGER)

    def _send(self, taken: list[tuple[bytes, bytes]]) -> None:
        with self._lock:
            importers = {topic: set(agents) for topic, agents in self._importers.items()}
            resend, self._resend = self._resend, []
            session, publishers = self._session, self._publishers
        out: dict[str, list[bytes]] = collections.defaultdict(list)
        for agent, topic in resend:
            out[agent].extend(self._latched[topic])
        for topic_bytes, message in taken:
            topic = topic_bytes.decode()
            echoes = self._echoes.get(topic)
            if echoes is not None and echoes.is_echo(message):
                continue
            one = record(topic_bytes, message)
            if topic in self._latched:
                self._latched[topic].append(one)
            for agent in importers.get(topic, ()):
                out[agent].append(one)
        if session is not None and out:
            self._put(session, publishers, out)

    def _put(self, session, publishers: dict[str, Any], out: dict[str, list[bytes]]) -> None:
        import zenoh

        from fleet.wire.protocol import batch_key

        for agent, records in out.items():
            try:
                if (publisher := publishers.get(agent)) is None:
                    # A declared publisher, not a put with the key's text: the router resolves
                    # the key once, not for every batch.
                    publisher = publishers[agent] = session.declare_publisher(
                        batch_key(self.fleet, agent), congestion_control=zenoh.CongestionControl.DROP
                    )
                for payload in batches(records):
                    publisher.put(payload)
                    self.puts += 1
            except Exception:  # the session is being replaced: lost, as on a cut link
                return
            self.sent += len(records)


class Importer:
    """Batches for this agent -> local topics, published with each route's QoS.  Zenoh's thread
    only queues a batch; this importer's own thread publishes its messages, so that the link
    from the router is read on while DDS takes its time (else the router, finding its queue
    towards us full, drops what follows)."""

    def __init__(self, fleet: str, agent: str, routes, node, echoes: dict[str, Echoes]) -> None:
        self.fleet, self.agent, self.routes = fleet, agent, list(routes)
        self._echoes = echoes
        self.received = 0
        self.dropped = 0  # batches that found the queue full
        self._malformed_logged = False
        self._queue: queue.Queue[bytes | None] = queue.Queue(maxsize=IMPORT_QUEUE)
        self._publishers = {
            route.name: node.create_publisher(message_class(route.type), route.name, ros_qos(route))
            for route in self.routes
        }
        self._thread = threading.Thread(target=self._run, name="fleet-bridge-import", daemon=True)

    def attach(self, session) -> list[Any]:
        """The batch subscriber first, then the tokens: an exporter that sees a token reaches us."""
        from fleet.wire.protocol import batch_key, import_token_key

        keep: list[Any] = [session.declare_subscriber(batch_key(self.fleet, self.agent), self._queued)]
        liveliness = session.liveliness()
        keep += [liveliness.declare_token(import_token_key(self.fleet, self.agent, r.name)) for r in self.routes]
        return keep

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        if self._thread.is_alive():
            with contextlib.suppress(queue.Full):
                self._queue.put(None, timeout=1.0)
            self._thread.join(timeout=5.0)

    def _queued(self, sample) -> None:  # Zenoh thread: queue and return
        try:
            self._queue.put_nowait(sample.payload.to_bytes())
        except queue.Full:
            self.dropped += 1

    def _run(self) -> None:
        while (payload := self._queue.get()) is not None:
            self._publish(payload)

    def _publish(self, payload: bytes) -> None:
        try:
            for topic, message in messages(payload):
                publisher = self._publishers.get(topic)
                if publisher is not None:
                    if (echoes := self._echoes.get(topic)) is not None:
                        echoes.brought_in(message)
                    publisher.publish(message)
                    self.received += 1
        except BatchError as error:
            if not self._malformed_logged:  # once: a stranger putting on our key must not flood the log
                log.warning("ignoring a malformed batch: %s", error)
                self._malformed_logged = True


class Bridge:
    """The ROS side is made once; the Zenoh side can be made again on a new session (attach),
    when the router stops echoing this bridge's probe (see main)."""

    def __init__(self, fleet: str, agent: str, exports, imports, node) -> None:
        self.fleet, self.agent = fleet, agent
        # Topics both sent and brought in (shared by templates): what we publish we hear again.
        both = {route.name for route in exports} & {route.name for route in imports}
        echoes = {name: Echoes() for name in both}
        self.exporter = Exporter(fleet, agent, exports, node, echoes) if exports else None
        self.importer = Importer(fleet, agent, imports, node, echoes) if imports else None
        self.last_echo = 0.0  # time.monotonic() of the router's last echo of our probe
        self._keep: list[Any] = []  # the current session's declarations

    @property
    def counts(self) -> dict[str, int]:
        return {
            "out": self.exporter.sent if self.exporter else 0,
            "puts": self.exporter.puts if self.exporter else 0,
            "dropped": self.importer.dropped if self.importer else 0,
            "in": self.importer.received if self.importer else 0,
        }

    def attach(self, session) -> None:
        """Declare the Zenoh side on `session` (replacing what an earlier session had)."""
        from fleet.wire.protocol import echo_keys

        keep: list[Any] = []
        if self.importer:
            keep += self.importer.attach(session)
        if self.exporter:
            keep += self.exporter.attach(session)
        ping, pong = echo_keys(self.fleet, self.agent)
        keep.append(session.declare_subscriber(pong, self._echoed))
        self._ping = session.declare_publisher(ping)
        self._keep = [*keep, self._ping]
        self.last_echo = time.monotonic()  # the new session gets its full grace period

    def start(self) -> None:
        for side in (self.exporter, self.importer):
            if side:
                side.start()

    def stop(self) -> None:
        for side in (self.exporter, self.importer):
            if side:
                side.stop()

    def probe(self) -> None:
        with contextlib.suppress(Exception):  # a closed session: the next attach replaces it
            self._ping.put(b"?")

    def _echoed(self, sample) -> None:
        self.last_echo = time.monotonic()


# A bridge reads its one link (to the router) on Zenoh's application thread instead of the two
# threads of Zenoh's own rx runtime: the `zenoh` transport's crossing took 0.05 ms less by the
# median of 8 pairs (bench/README.md), where one rx thread of its own gained nothing.  Not in the
# router (0.14 ms with it there): one thread would read all its links, and with that a robot on a
# live computer was once seen degraded while another computer's cable was out.  Nor tx: handing
# it over too left an 8 MiB request unanswered.
ZENOH_RUNTIME = "(rx: (handover: app))"


def _open_session(connect: list[str], zenoh_config: Path | None, stop: threading.Event):
    from fleet.wire.session import AGENT_LEASE_MS, open_client_retrying

    return open_client_retrying(connect, zenoh_config, AGENT_LEASE_MS, stop, SESSION_SETTINGS, ZENOH_RUNTIME)


def _replace_session(session, bridge: Bridge, connect: list[str], zenoh_config: Path | None, stop: threading.Event):
    """A new session for a connected one that the router no longer echoes (seen after a link to
    the router dropped and came back: Zenoh reconnected, but nothing reached this bridge)."""
    log.warning("the router has not echoed this bridge for %.0f s: opening a new Zenoh session", ECHO_TIMEOUT)
    with contextlib.suppress(Exception):  # a broken session may not close cleanly: drop it anyway
        session.close()
    session = _open_session(connect, zenoh_config, stop)
    if session is not None:
        bridge.attach(session)
    return session


def main(argv: list[str]) -> int:
    logging.basicConfig(level=logging.INFO, format="%(asctime)s fleet.bridge %(levelname)s %(message)s")
    from fleet.wire.protocol import BridgeRoutes

    try:
        config = json.loads(Path(argv[0]).read_text())
        routes = BridgeRoutes(exports=config["exports"], imports=config["imports"])
        fleet, agent, connect = config["fleet"], config["agent"], list(config["connect"])
        zenoh_config = Path(config["zenoh_config"]) if config.get("zenoh_config") else None
    except (IndexError, OSError, ValueError, KeyError, TypeError) as error:
        print(f"fleet bridge: error: bad config: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    from fleet.dataplane.receive_buffers import use_large_receive_buffers
    from fleet.rules import HELPER_ROS_ARGS, service_node_name
    from fleet.runtime.processes import stop_on_signals

    stop = stop_on_signals()
    if warning := use_large_receive_buffers(Path(argv[0]).with_suffix(".fastdds.xml")):
        log.warning("%s", warning)
    rclpy.init(args=list(HELPER_ROS_ARGS), signal_handler_options=SignalHandlerOptions.NO)
    # No executor: the exporter takes messages itself, and nothing else here needs spinning.
    node = rclpy.create_node(service_node_name("bridge", fleet), start_parameter_services=False)
    bridge = Bridge(fleet, agent, routes.exports, routes.imports, node)
    session = _open_session(connect, zenoh_config, stop)
    try:
        if session is None:
            return 0
        bridge.attach(session)
        log.info(
            "bridge of fleet %s: %d topics out, %d in, through %s",
            fleet,
            len(routes.exports),
            len(routes.imports),
            ", ".join(connect),
        )
        bridge.start()
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
                        "last %.0f s: %d messages out in %d puts, %d in, %d batches dropped (routers: %d)",
                        STATS_PERIOD,
                        now["out"] - last["out"],
                        now["puts"] - last["puts"],
                        now["in"] - last["in"],
                        now["dropped"] - last["dropped"],
                        routers,
                    )
                last = now
        log.info(
            "bridge of fleet %s stopping: %d messages out, %d in, %d batches dropped (import queue full)",
            fleet,
            bridge.counts["out"],
            bridge.counts["in"],
            bridge.counts["dropped"],
        )
    finally:
        bridge.stop()
        node.destroy_node()
        rclpy.try_shutdown()
        if session is not None:
            session.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
