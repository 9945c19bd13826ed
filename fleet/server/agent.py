"""The agent daemon: receives each fleet's desired state, persists it, and runs it.

Threads, and why:
- Zenoh callbacks only hand the query to a small pool (`_requests`): a slow callback stalls the
  whole session.  Pool threads decode, validate, persist and reply.
- One reconcile thread starts and stops units, so applies are carried out one at a time and in
  order.  (Node processes die with the agent, even on SIGKILL: the runner's session threads
  fork them with PR_SET_PDEATHSIG.  Leftovers of anything else are found by their environment
  marker when the agent starts again.)
- One services thread runs each fleet's helper processes here, restarting them if they die:
  the DDS discovery server when the fleet names this agent its host, the Zenoh bridge when the
  fleet's transport is `zenoh` (fleet.dataplane).  They too die with the agent.
- Nothing is published: status and world state are answered when asked.  (Publishers declared
  on the keys of this session's own queryables made the session stall when the router's links
  changed; watchers such as `fleet dashboard` ask often instead.)
- The main thread owns the Zenoh session: it opens it (retrying while no router answers; robots
  keep running meanwhile) and closes it on shutdown.  Zenoh reconnects a client by itself when
  the router comes back, re-declaring queryables and liveliness tokens.  Every few seconds it
  asks the router for desired states newer than it holds (a deploy made while we were away or
  disconnected) and applies them like a received apply.
"""

from __future__ import annotations

import json
import logging
import os
import queue
import shutil
import socket
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

from fleet import __version__
from fleet.errors import SpecError
from fleet.files import write_atomic
from fleet.rules import PARAMS_SUFFIX, hosts_dir, hosts_root, services_dir
from fleet.runtime.node_log import logger_name
from fleet.runtime.processes import ServiceProcess, stop_all
from fleet.server.logs import robot_logs
from fleet.server.reconcile import plan_changes
from fleet.server.state import AgentStore, FleetState
from fleet.server.units import UNIT_MARKER, Unit
from fleet.spec.load import check_parameter_file
from fleet.spec.model import DEFAULT_GROUP_SIZE
from fleet.wire import protocol as p
from fleet.wire.session import AGENT_LEASE_MS, open_client_retrying

if TYPE_CHECKING:
    import zenoh

log = logging.getLogger("fleet.agent")

DESIRED_POLL = 3.0  # how often to ask the router for desired states newer than ours
DESIRED_TIMEOUT = 5.0
# Desired-state queries in a row that the connected router does not answer: the session has
# stalled (seen after a link to the router dropped and came back: Zenoh reconnected, but queries
# to and from this session went unanswered, timing out or ending at once with no reply, as in
# eclipse-zenoh/zenoh#2767), so it is replaced by a new one.
STALLED_FETCHES = 2
# After this long without an answer from a fleet's discovery host (absent, or its status denied to
# this agent by the router's access rules), say so; then again every as long.
UNANSWERED_HOST_WARNING = 30.0
WATCH_FRESH = 5.0  # s: a watch report older than this says nothing of the graph now (watch stuck?)
GRAPH_SETTLE = 3.0  # s a new watch learns the graph before an absent node counts as absent


@dataclass(frozen=True)
class FleetService:
    """What one of a fleet's helper processes here runs with, as the fleet's state decides it: a
    running service whose description changes (another server, other routes or topics) restarts."""

    server: str | None  # the fleet's DDS discovery server (address:port); what a discovery service serves
    routes: str = ""  # a bridge's topic routes (their JSON)
    topics: tuple[str, ...] = ()  # a watch's shared topics, whose publishers it counts
    nodes: bool = False  # whether a watch looks for the robots' nodes in the ROS graph


class Agent:
    def __init__(
        self,
        name: str,
        connect: list[str],
        state_dir: Path,
        zenoh_config: Path | None = None,
        address: str | None = None,
    ):
        from fleet.dataplane.discovery import address_towards

        problem = p.key_name_problem(name)
        if problem:
            raise ValueError(f"agent name {problem}")
        problem = p.address_problem(address) if address else None
        if problem:
            raise ValueError(f"--address: {problem}")
        self.name = name
        self.connect = connect
        self.zenoh_config = Path(zenoh_config).resolve() if zenoh_config else None
        self.store = AgentStore(Path(state_dir).resolve(), name)
        self.info = p.AgentInfo(
            name=name,
            hostname=socket.gethostname(),
            cores=os.cpu_count() or 1,
            ros_distro="jazzy",
            backends=available_backends(),
            pid=os.getpid(),
            version=__version__,
            started_at=time.time(),
            address=address or address_towards(connect),
        )
        self._started = time.monotonic()
        self._restored: set[str] = set()  # fleets restored from the state directory whose server has not run yet
        self._lock = threading.Lock()  # guards _fleets, _units, _reconciled, _tokens, _restarts_*
        self._fleets: dict[str, FleetState] = {}
        self._units: dict[tuple[str, str], Unit] = {}
        self._reconciled: dict[str, int] = {}
        self._tokens: dict[str, Any] = {}
        # Fleets whose discovery host has told this run of the agent its address (the address
        # itself is kept in the fleet's state, see _discovery_server): (fleet, host)
        self._confirmed_hosts: set[tuple[str, str]] = set()
        # (fleet, host) -> (monotonic time of the first unanswered ask, of the last warning)
        self._unanswered_hosts: dict[tuple[str, str], tuple[float, float]] = {}
        # (fleet, "discovery" | "bridge" | "watch") -> what it runs and its process, run by the
        # services thread
        self._services: dict[tuple[str, str], tuple[FleetService, ServiceProcess]] = {}
        # Fleets whose watch here looks for their robots' nodes in the ROS graph: from when a robot
        # of it has started a ROS node here (plain executables never join the graph) for as long
        # as it has robots here (one restarting runs no node for a moment: the watch, and the
        # graph it learnt, stay).  Known when robots start, not looked for at every services round
        # (100 idle agents of plain executables took 27% of a core looking, 19% not; bench/README).
        self._watching_nodes: set[str] = set()
        # (fleet, environment, group size) -> HostPool: the host processes of isolation: agent
        self._hosting: dict[tuple[str, str, int], Any] = {}
        self._pools_made = 0  # numbers their directories: a pool dropped when idle leaves a gap
        # (fleet, unit) -> `fleet restart`s asked for, and those the reconcile thread has yet to carry out
        self._restarts_asked: dict[tuple[str, str], int] = {}
        self._restarts_due: set[tuple[str, str]] = set()
        self._work: queue.Queue[str | None] = queue.Queue()
        self._requests = ThreadPoolExecutor(max_workers=4, thread_name_prefix="fleet-agent-req")
        # Parameter calls take seconds (an rclpy helper process): their own pool, so status and
        # apply never queue behind them.
        self._slow_requests = ThreadPoolExecutor(max_workers=2, thread_name_prefix="fleet-agent-param")
        self._session: zenoh.Session | None = None
        self.stop_event = threading.Event()

    # -- life cycle ------------------------------------------------------------------------------

    def run(self) -> None:
        """Restore, serve until stop_event is set, then stop every unit."""
        from fleet.runtime.hosting import remove_orphaned_socket_dirs

        self.store.claim()
        # Like any daemon, do not keep the directory we were started from: node processes
        # inherit our working directory, and one that happens to hold a Python project (the
        # fleet checkout itself, say) can change what they import.
        os.chdir(self.store.root)
        stop_leftover_processes(self.store.root)
        remove_orphaned_socket_dirs(hosts_root(self.store.root))
        self._restore()
        worker = threading.Thread(target=self._reconcile_loop, name="fleet-agent-reconcile")
        worker.start()
        services = threading.Thread(target=self._services_loop, name="fleet-agent-services")
        services.start()
        try:
            self._session = open_client_retrying(self.connect, self.zenoh_config, AGENT_LEASE_MS, self.stop_event)
            if self._session is not None:
                self._declare(self._session)
                log.info("agent %s connected to the router at %s", self.name, ", ".join(self.connect))
                self._serve()
        finally:
            self.stop_event.set()
            stopping = time.monotonic()
            log.info("agent %s stopping", self.name)
            session, self._session = self._session, None
            if session is not None:
                with self._lock:
                    self._tokens.clear()
                session.close()
            self._requests.shutdown(wait=True, cancel_futures=True)
            self._slow_requests.shutdown(wait=True, cancel_futures=True)
            self._work.put(None)
            worker.join()
            services.join()
            log.info("agent %s stopped its robots and services in %.1f s", self.name, time.monotonic() - stopping)

    def _serve(self) -> None:
        """Until stopped: fetch desired states every DESIRED_POLL seconds, and replace the session
        when the connected router stops answering (STALLED_FETCHES in a row)."""
        next_fetch, stalled = 0.0, 0
        while not self.stop_event.is_set() and self._session is not None:
            if time.monotonic() >= next_fetch:
                stalled = 0 if self._fetch_desired(self._session) else stalled + 1
                self._find_discovery_hosts(self._session)
                next_fetch = time.monotonic() + DESIRED_POLL
                if stalled >= STALLED_FETCHES:
                    self._reopen_session()
                    stalled = 0
            self.stop_event.wait(min(0.5, DESIRED_POLL))  # a timed wait lets signal handlers run

    def _restore(self) -> None:
        fleets, problems = self.store.load()
        for problem in problems:
            log.error("cannot restore desired state: %s", problem)
        with self._lock:
            self._fleets = fleets
        self._restored = set(fleets)
        for fleet in fleets:
            self._work.put(fleet)

    def _reopen_session(self) -> None:
        """Close the stalled session and serve on a new one (robots keep running throughout)."""
        log.warning("the Zenoh session stopped answering: opening a new one")
        session, self._session = self._session, None
        with self._lock:
            self._tokens.clear()
        if session is not None:
            try:
                session.close()
            except Exception as error:  # a broken session may not close cleanly: drop it anyway
                log.warning("closing the stalled session: %s", error)
        self._session = open_client_retrying(self.connect, self.zenoh_config, AGENT_LEASE_MS, self.stop_event)
        if self._session is not None:
            self._declare(self._session)
            log.info("agent %s serving again on %s", self.name, ", ".join(self.connect))

    def _declare(self, session) -> None:
        # One queryable per operation, with a wildcard fleet chunk: we serve every fleet sent to us.
        handlers = {
            p.apply_key("*", self.name): self._handle_apply,
            p.logs_key("*", self.name): self._handle_logs,
            p.param_key("*", self.name): self._handle_param,  # on the slow pool, see _enqueue
            p.restart_key("*", self.name): self._handle_restart,
            p.agent_status_key("*", self.name): self._handle_status,
            p.world_key("*", self.name): self._handle_world,
        }
        self._queryables = []
        for key, handler in handlers.items():
            self._queryables.append(session.declare_queryable(key, self._enqueue(handler)))
        self._update_tokens()

    def _enqueue(self, handler):
        pool = self._slow_requests if handler == self._handle_param else self._requests

        def on_query(query) -> None:  # runs on a Zenoh thread: hand over, nothing else
            try:
                pool.submit(self._answer, handler, query)
            except RuntimeError:  # pool shut down: we are stopping
                query.drop()

        return on_query

    def _answer(self, handler, query) -> None:
        try:
            try:
                for key, payload in handler(query):
                    query.reply(key, payload)
            except p.ProtocolError as error:
                query.reply_err(p.error_reply(error))
            except Exception as error:  # never let a request take the agent down
                log.exception("request on %s failed", query.key_expr)
                query.reply_err(p.error_reply(p.ProtocolError(f"agent error: {error}", "agent_error")))
        finally:
            query.drop()  # sends the final reply now, not whenever the object is collected

    def _update_tokens(self) -> None:
        """A liveliness token per served fleet (one with robots), so `fleet status` sees us."""
        session = self._session
        if session is None:
            return
        with self._lock:
            served = {fleet for fleet, state in self._fleets.items() if state.request.bundles}
            for fleet in set(self._tokens) - served:
                self._tokens.pop(fleet).undeclare()
            for fleet in served - set(self._tokens):
                self._tokens[fleet] = session.liveliness().declare_token(p.alive_key(fleet, self.name))

    # -- apply ------------------------------------------------------------------------------------

    def _handle_apply(self, query):
        request = self._check_apply(_payload(query), query.key_expr)
        reply = self.check(request) if request.check_only else self.apply(request)
        yield p.apply_key(request.fleet, self.name), p.encode(reply)

    def check(self, request: p.ApplyRequest) -> p.ApplyReply:
        """Whether every robot this apply would start or change could start here; nothing changes."""
        from fleet.server.units import launch_problem

        with self._lock:
            held = self._fleets.get(request.fleet)
            running = {
                name: (unit.bundle.digest, unit.bundle.hot_digest)
                for (fleet, name), unit in self._units.items()
                if fleet == request.fleet and unit.session is not None
            }
        env = self._unit_env(request.domain_id, None)
        problems = {}
        for bundle in request.bundles:
            if running.get(bundle.name) != (bundle.digest, bundle.hot_digest):
                problem = launch_problem(bundle, env)
                if problem:
                    problems[bundle.name] = problem
        return p.ApplyReply(
            fleet=request.fleet,
            agent=self.name,
            generation=request.generation,
            accepted=not problems,
            current_generation=held.generation if held else 0,
            reason="; ".join(f"{name}: {problem}" for name, problem in sorted(problems.items())),
            problems=problems,
        )

    def _check_apply(self, payload: bytes | None, key) -> p.ApplyRequest:
        """Decode and validate an apply (received, or fetched from the router); ProtocolError if bad."""
        request = _request_on_its_key(payload, key, p.ApplyRequest)
        if request.agent != self.name:
            raise p.ProtocolError(f"this is agent {self.name!r}, not {request.agent!r}", "wrong_agent")
        for bundle in request.bundles:
            if not bundle.digest_matches():
                raise p.ProtocolError(f"bundle {bundle.name!r}: its digest is not that of its files", "invalid")
            for name, text in bundle.files.items():
                if name.endswith(PARAMS_SUFFIX):
                    # A parameter file's nodes would read it at start, and crash-loop on one rcl
                    # cannot read: refused before it replaces anything running.
                    try:
                        check_parameter_file(text, f"{bundle.name}/{name}")
                    except SpecError as error:
                        raise p.ProtocolError(
                            f"bundle {bundle.name!r}: {error.location}: {error.message}", "invalid"
                        ) from None
        return request

    def _fetch_desired(self, session) -> bool:
        """Apply what the router stored for us if it is newer than what we hold (a deploy or a
        `fleet down` made while we were away).  Bad data is logged and leaves our state alone.
        False when the router is connected but did not answer: its answer always includes
        DesiredDone, so a query that times out or gets no reply at all means the session stalled."""
        import zenoh

        with self._lock:
            held = {fleet: state.generation for fleet, state in self._fleets.items()}
        try:
            replies = session.get(
                p.desired_key("*", self.name),
                payload=p.encode(p.DesiredQuery(held=held)),
                target=zenoh.QueryTarget.ALL,
                consolidation=zenoh.ConsolidationMode.NONE,
                timeout=DESIRED_TIMEOUT,
            )
            answered = False
            for reply in replies:
                if reply.ok is None:
                    log.warning("router refused the desired-state query: %s", reply.err.payload.to_bytes()[:200])
                    continue
                if p.fleet_of_key(reply.ok.key_expr) is None:  # the router's DesiredDone
                    answered = True
                    continue
                try:
                    request = self._check_apply(reply.ok.payload.to_bytes(), reply.ok.key_expr)
                except p.ProtocolError as error:
                    log.error("ignoring desired state from %s: %s", reply.ok.key_expr, error)
                    continue
                if request.generation <= held.get(request.fleet, -1):
                    continue  # never go back: the later generation wins
                result = self.apply(request)
                log.info(
                    "fetched desired state of fleet %s, generation %d: %s",
                    request.fleet,
                    request.generation,
                    "accepted" if result.accepted else result.reason,
                )
        except zenoh.ZError as error:  # no router right now: the next round tries again
            log.debug("cannot fetch desired states: %s", error)
        except Exception:  # never let this take the agent down: the next round tries again
            log.exception("fetching desired states failed")
        else:  # without a router connected, silence says nothing about the session
            return answered or not list(session.info.routers_zid())
        return True

    def apply(self, request: p.ApplyRequest) -> p.ApplyReply:
        """Accept (persist, then schedule) or refuse one desired state; serialised by the lock."""
        with self._lock:
            held = self._fleets.get(request.fleet)
            held_generation = held.generation if held else -1
            reply = p.ApplyReply(
                fleet=request.fleet,
                agent=self.name,
                generation=request.generation,
                accepted=False,
                current_generation=max(held_generation, 0),
            )
            if request.generation < held_generation:
                reply.reason = f"superseded: this agent already holds generation {held_generation}"
                return reply
            if (
                held is not None
                and request.generation == held_generation
                and held.content_digest != request.content_digest()
            ):
                reply.reason = f"generation {held_generation} was already applied with other content"
                return reply
            state = FleetState(request=request)
            if held and not request.discovery_server and held.request.discovery_host == request.discovery_host:
                state.discovery_host_address = held.discovery_host_address  # still that host's
            current = {b.name: b for b in held.request.bundles} if held else {}
            desired = {b.name: b for b in request.bundles}
            # Units that failed are tried again; units that would run in another ROS environment
            # (the fleet's discovery server moved, or its domain) restart: the reply says so, as
            # the reconcile does it.
            env = self._unit_env(request.domain_id, self._discovery_server(state))
            again = {
                name
                for (fleet, name), unit in self._units.items()
                if fleet == request.fleet and (unit.error or (unit.session is not None and unit.env != env))
            }
            changes = plan_changes(current, desired, again)
            # Overrides survive redeploys of a robot whose description is unchanged, restarted or
            # not (in another ROS environment, or after a failure); a changed robot gets the spec's.
            if held:
                state.overrides = {
                    robot: values
                    for robot, values in held.overrides.items()
                    if robot in current and robot in desired and current[robot].digest == desired[robot].digest
                }
            # What it runs came with an earlier deploy only when this one leaves it unchanged.
            kept = held.deployed if held else {}
            state.deployed = {
                name: kept.get(name, held.generation) if held and name in changes.unchanged else request.generation
                for name in desired
            }
            self.store.save(state)  # persisted before we acknowledge
            self._fleets[request.fleet] = state
            # Units already running exactly this bundle are at the new generation now: saying so
            # at once lets a no-op deploy finish on its first status poll.
            for name in changes.unchanged:
                unit = self._units.get((request.fleet, name))
                if (
                    unit is not None
                    and unit.session is not None
                    and not unit.error
                    and (unit.bundle.digest, unit.bundle.hot_digest) == (desired[name].digest, desired[name].hot_digest)
                ):
                    unit.generation = request.generation
        self._work.put(request.fleet)
        self._update_tokens()
        reply.accepted = True
        reply.current_generation = request.generation
        reply.changes = changes
        return reply

    # -- reconcile ------------------------------------------------------------------------------

    def _reconcile_loop(self) -> None:
        while True:
            fleet = self._work.get()
            if fleet is None:
                break
            pending = {fleet}
            while True:  # coalesce a burst of applies into one pass per fleet
                try:
                    more = self._work.get_nowait()
                except queue.Empty:
                    break
                if more is None:
                    self._work.put(None)
                    break
                pending.add(more)
            for name in sorted(pending):
                try:
                    self._reconcile(name)
                except Exception:
                    log.exception("reconciling fleet %s failed", name)
        self._stop_all_units()

    def _reconcile(self, fleet: str) -> None:
        with self._lock:
            state = self._fleets.get(fleet)
            if state is None:
                return
            desired = {b.name: b for b in state.request.bundles}
            units = {name: unit for (f, name), unit in self._units.items() if f == fleet}
            overrides = {robot: dict(values) for robot, values in state.overrides.items()}
            generation = state.generation
            deployed = dict(state.deployed)
            env = self._unit_env(state.request.domain_id, self._discovery_server(state))
            asked = {name for (f, name) in self._restarts_due if f == fleet}
            self._restarts_due -= {(fleet, name) for name in asked}
            restarted = {name: count for (f, name), count in self._restarts_asked.items() if f == fleet}
        # A unit whose environment is not this one (the fleet's discovery server moved) restarts.
        running = {name: unit for name, unit in units.items() if name in desired and unit.session is not None}
        moved = sorted(name for name, unit in running.items() if unit.env != env)
        if moved:
            log.info(
                "fleet %s: restarting %s in the fleet's new ROS environment (domain %s, DDS discovery server %s)",
                fleet,
                ", ".join(moved),
                env["ROS_DOMAIN_ID"],
                env.get("ROS_DISCOVERY_SERVER", "none"),
            )
        changes = plan_changes(
            {name: unit.bundle for name, unit in units.items()},
            desired,
            {name for name, unit in units.items() if unit.error or unit.session is None or unit.env != env} | asked,
        )
        # Stop first (in parallel: each stop may wait seconds for a node to exit), then start.
        stop_all(units[name].stop for name in changes.stop + changes.restart)
        with self._lock:
            for name in changes.stop:
                self._units.pop((fleet, name), None)
        for name in changes.start + changes.restart:
            hosts = self._host_pool(fleet, env, desired[name])
            unit = Unit(fleet, desired[name], self.store.unit_dir(fleet, name), env, hosts)
            unit.generation = generation
            unit.deployed_generation = deployed.get(name, generation)
            unit.restarted = restarted.get(name, 0)
            with self._lock:
                self._units[(fleet, name)] = unit
            unit.start(overrides.get(name, {}))
            if unit.hosted or any(node.ros for node in unit.node_states()):  # hosted nodes are ROS nodes
                with self._lock:
                    self._watching_nodes.add(fleet)
            if unit.error:
                log.error("robot %s of fleet %s failed to start: %s", name, fleet, unit.error)
        for name in changes.hot_update:
            units[name].hot_update(desired[name], overrides.get(name, {}))
            units[name].deployed_generation = deployed.get(name, generation)
        for name in changes.hot_update + changes.unchanged:
            units[name].generation = generation
        with self._lock:
            self._reconciled[fleet] = generation
        self._drop_idle_host_pools()
        for name in changes.stop:
            shutil.rmtree(self.store.unit_dir(fleet, name), ignore_errors=True)

    def _host_pool(self, fleet: str, env: dict[str, str], bundle: p.BundleMessage):
        """The host processes of isolation: agent for this robot (None: it runs its own)."""
        from fleet.runtime.hosting import HostPool
        from fleet.runtime.isolation import HOSTED

        if bundle.options.get("isolation") != HOSTED:
            return None
        group_size = int(bundle.options.get("group_size", "0") or 0) or DEFAULT_GROUP_SIZE
        key = (fleet, json.dumps(env, sort_keys=True), group_size)
        with self._lock:
            pool = self._hosting.get(key)
            if pool is None:
                self._pools_made += 1
                directory = hosts_dir(self.store.root, fleet, self._pools_made)
                pool = self._hosting[key] = HostPool(directory, env, group_size)
        return pool

    def _drop_idle_host_pools(self) -> None:
        with self._lock:
            idle = [key for key, pool in self._hosting.items() if not pool.robots()]
            pools = [self._hosting.pop(key) for key in idle]
        for pool in pools:
            pool.stop()

    def _unit_env(self, domain_id: int, discovery_server: str | None) -> dict[str, str]:
        from fleet.runtime.environment import ros_environment

        env = ros_environment(domain_id, discovery_server=discovery_server)
        env[UNIT_MARKER] = str(self.store.root)
        return env

    # -- fleet services: discovery server, Zenoh bridge ----------------------------------------

    def _wanted_services(self) -> dict[tuple[str, str], tuple[FleetService, FleetState]]:
        """(fleet, "discovery" | "bridge" | "watch") -> (what it runs, fleet state) of every
        service this agent should run."""
        wanted: dict[tuple[str, str], tuple[FleetService, FleetState]] = {}
        with self._lock:
            states = [state for state in self._fleets.values() if state.request.bundles]
        with self._lock:
            self._watching_nodes &= {state.request.fleet for state in states}
        for state in states:
            request, server = state.request, self._discovery_server(state)
            if server and request.discovery_host == self.name:
                wanted[(request.fleet, "discovery")] = (FleetService(server), state)
            if request.transport == "zenoh" and (request.bridge.exports or request.bridge.imports):
                wanted[(request.fleet, "bridge")] = (
                    FleetService(server, routes=request.bridge.model_dump_json()),
                    state,
                )
            with self._lock:
                nodes = request.fleet in self._watching_nodes
            if request.shared or nodes:
                topics = tuple(topic.name for topic in request.shared)
                wanted[(request.fleet, "watch")] = (FleetService(server, topics=topics, nodes=nodes), state)
        return wanted

    def _discovery_server(self, state: FleetState) -> str | None:
        """The fleet's DDS discovery server ("address:port"), as its deploy said.  A deploy made
        while the host was offline names only the host: it serves at its own address, and the
        other agents use the address it gave when asked (None until then: their nodes stay on
        this computer, and the fleet's robots are restarted with the server once it is found).
        That address is kept with the fleet's state, so that an agent started again starts its
        robots with the server at once; it asks the host again all the same, in case it moved."""
        request = state.request
        if request.discovery_server or request.discovery_host is None:
            return request.discovery_server
        from fleet.runtime.environment import discovery_server_port

        address = self.info.address if request.discovery_host == self.name else state.discovery_host_address
        return f"{address}:{discovery_server_port(request.domain_id)}" if address else None

    def _find_discovery_hosts(self, session) -> None:
        """Ask the discovery host of each fleet that needs its address, and has not had it from
        the host since this agent started, for that address (its status reply says it); a fleet
        whose server changes is reconciled with the new one."""
        with self._lock:
            waiting = {
                (fleet, request.discovery_host)
                for fleet, request in ((fleet, state.request) for fleet, state in self._fleets.items())
                if request.bundles
                and request.discovery_host not in (None, self.name)
                and not request.discovery_server
                and (fleet, request.discovery_host) not in self._confirmed_hosts
            }
        for key in set(self._unanswered_hosts) - waiting:
            del self._unanswered_hosts[key]
        for fleet, host in sorted(waiting):
            try:
                replies = list(session.get(p.agent_status_key(fleet, host), timeout=DESIRED_TIMEOUT))
            except Exception as error:  # no router right now: the next round asks again
                log.debug("cannot ask agent %s for its address: %s", host, error)
                continue
            if not any(reply.ok is not None for reply in replies):
                self._warn_unanswered(fleet, host)
            for reply in replies:
                if reply.ok is None:
                    continue
                try:
                    address = p.decode(reply.ok.payload.to_bytes(), p.StatusReply).agent.address
                except p.ProtocolError as error:
                    log.error("ignoring the status of agent %s: %s", host, error)
                    continue
                if p.address_problem(address):
                    log.error("agent %s reports no address others can reach: %s", host, p.address_problem(address))
                    break
                with self._lock:
                    state = self._fleets.get(fleet)
                    if state is None or state.request.discovery_host != host:
                        break  # a deploy replaced the fleet's state meanwhile
                    self._confirmed_hosts.add((fleet, host))
                    if state.discovery_host_address == address:
                        break
                    state.discovery_host_address = address
                    self.store.save(state)
                log.info("fleet %s: its discovery server runs on agent %s at %s", fleet, host, address)
                self._work.put(fleet)
                break

    def _warn_unanswered(self, fleet: str, host: str) -> None:
        """Warn when the discovery host has not answered for UNANSWERED_HOST_WARNING seconds."""
        now = time.monotonic()
        first, warned = self._unanswered_hosts.setdefault((fleet, host), (now, now))
        if now - warned < UNANSWERED_HOST_WARNING:
            return
        self._unanswered_hosts[(fleet, host)] = (first, now)
        log.warning(
            "fleet %s: agent %s, its discovery host, has not answered for %.0f s (is it running? or do the "
            "router's access rules deny this agent its status?): robots here run without the fleet's "
            "discovery server until it does",
            fleet,
            host,
            now - first,
        )

    def _service(self, fleet: str, kind: str, service: FleetService, state: FleetState) -> ServiceProcess:
        from fleet.dataplane.discovery import discovery_server

        request = state.request
        directory = services_dir(self.store.root)
        if kind == "discovery":
            assert service.server is not None  # wanted only where the fleet has a server
            log_file = directory / f"{fleet}.discovery.log"
            # A fleet restored from the state directory had its server run by this agent's
            # predecessor, which may have died (and its server with it) just before we started.
            down_since = self._started if fleet in self._restored else None
            self._restored.discard(fleet)
            return discovery_server(service.server, self._unit_env(request.domain_id, None), log_file, down_since)
        if kind == "watch":
            return self._shared_watch(fleet, service, state)
        config = directory / f"{fleet}.bridge.json"
        directory.mkdir(parents=True, exist_ok=True)
        write_atomic(
            config,
            json.dumps(
                {
                    "fleet": fleet,
                    "agent": self.name,
                    "connect": self.connect,
                    "zenoh_config": str(self.zenoh_config) if self.zenoh_config else None,
                    "exports": [r.model_dump() for r in request.bridge.exports],
                    "imports": [r.model_dump() for r in request.bridge.imports],
                }
            ),
        )
        command = [sys.executable, "-m", "fleet.dataplane.bridge", str(config)]
        env = self._unit_env(request.domain_id, service.server)
        return ServiceProcess(command, env, directory / f"{fleet}.bridge.log")

    def _shared_watch(self, fleet: str, service: FleetService, state: FleetState) -> ServiceProcess:
        """The fleet's watch of its shared topics and its robots' nodes (fleet.dataplane.watch): a
        discovery super client."""
        directory = services_dir(self.store.root)
        directory.mkdir(parents=True, exist_ok=True)
        config = directory / f"{fleet}.watch.json"
        status_file = directory / f"{fleet}.watch.status.json"
        status_file.unlink(missing_ok=True)  # counts of an earlier watch are not this one's
        settings = {
            "fleet": fleet,
            "topics": list(service.topics),
            "nodes": service.nodes,
            "status_file": str(status_file),
        }
        write_atomic(config, json.dumps(settings))
        env = self._unit_env(state.request.domain_id, service.server)
        if "ROS_DISCOVERY_SERVER" in env:
            env["ROS_SUPER_CLIENT"] = "TRUE"  # sees every publisher without subscribing
        command = [sys.executable, "-m", "fleet.dataplane.watch", str(config)]
        return ServiceProcess(command, env, directory / f"{fleet}.watch.log")

    def _watch_report(self, fleet: str) -> dict[str, Any] | None:
        """What this agent's watch of the fleet last wrote (None while it has written nothing)."""
        try:
            data = json.loads((services_dir(self.store.root) / f"{fleet}.watch.status.json").read_text())
            return data if isinstance(data, dict) else None
        except (OSError, ValueError):
            return None

    def _services_loop(self) -> None:
        """Run the services of every fleet that wants them here; stop those no longer wanted."""
        services = self._services  # entries replaced only under the lock (status reads them)
        try:
            while not self.stop_event.is_set():
                wanted = self._wanted_services()
                for name in list(services):
                    if name not in wanted or wanted[name][0] != services[name][0]:
                        with self._lock:
                            _, process = services.pop(name)
                        process.stop()
                for name, (service, state) in wanted.items():
                    try:
                        if name not in services:
                            process = self._service(*name, service, state)
                            with self._lock:
                                services[name] = (service, process)
                        services[name][1].keep_running()
                    except OSError as error:
                        log.error("cannot run the %s of fleet %s: %s", name[1], name[0], error)
                self.stop_event.wait(0.5)
        finally:
            with self._lock:
                stopping = [process for _, process in services.values()]
                services.clear()
            for process in stopping:
                process.stop()

    def _stop_all_units(self) -> None:
        with self._lock:
            units = list(self._units.values())
            self._units.clear()
        stop_all(unit.stop for unit in units)
        with self._lock:
            pools = list(self._hosting.values())
            self._hosting.clear()
        for pool in pools:
            pool.stop()

    # -- status ---------------------------------------------------------------------------------

    def _handle_status(self, query):
        wanted = p.fleet_of_key(query.key_expr)
        with self._lock:
            served = sorted(f for f, s in self._fleets.items() if s.request.bundles)
        if wanted and wanted not in served:  # online, but running nothing of that fleet
            yield p.agent_status_key(wanted, self.name), p.encode(self.status(None))
            return
        if not wanted and not served:  # idle agent asked about every fleet: still say we are here
            yield p.agent_status_key("*", self.name), p.encode(self.status(None))
        for fleet in [wanted] if wanted else served:
            yield p.agent_status_key(fleet, self.name), p.encode(self.status(fleet))

    def status(self, fleet: str | None) -> p.StatusReply:
        with self._lock:
            state = self._fleets.get(fleet) if fleet else None
            units = sorted(
                ((name, unit) for (f, name), unit in self._units.items() if f == fleet), key=lambda item: item[0]
            )
            reconciled = self._reconciled.get(fleet, 0) if fleet else 0
            overrides = dict(state.overrides) if state else {}
            discovery = self._services.get((fleet, "discovery")) if fleet else None
            bridge = self._services.get((fleet, "bridge")) if fleet else None
            watching = (fleet, "watch") in self._services
        reply = p.StatusReply(agent=self.info, fleet=fleet, time=time.time())
        if state is None:
            return reply
        reply.generation = state.generation
        reply.reconciled_generation = reconciled
        reply.content_digest = state.content_digest
        reply.domain_id = state.request.domain_id
        reply.has_world = state.request.has_world
        reply.discovery_in_use = self._discovery_server(state) or ""
        if discovery is not None:
            reply.discovery_server, reply.discovery_pid = discovery[0].server or "", discovery[1].pid
        if bridge is not None:
            reply.bridge_pid = bridge[1].pid
        watch = self._watch_report(fleet) if fleet and watching else None  # no file read for an unwatched fleet
        if state.request.shared:
            reply.shared_topics = _shared_topics(watch)
        graph = _graph_report(watch)
        seen = set()
        desired = {bundle.name for bundle in state.request.bundles}
        for name, unit in units:
            robot = unit.state(overrides.get(name, {}))
            if graph is not None:
                for node in robot.nodes:
                    node.in_graph = _seen_in_graph(node, graph) if node.ros else None
            if robot.state == "stopped" and name in desired:
                # The reconcile thread stops it to start it again (a new description): what it
                # will run is accepted and not started yet.
                robot.state, robot.reason = "pending", "restarting: its previous nodes stop, then the new ones start"
                robot.deployed_generation = state.deployed.get(name, 0)
            reply.robots.append(robot)
            world = unit.world_summary()
            if world is not None:
                reply.world = world
            seen.add(name)
        for bundle in state.request.bundles:  # accepted, not yet started by the reconcile thread
            if bundle.name not in seen:
                reply.robots.append(
                    p.RobotState(
                        name=bundle.name,
                        kind=bundle.kind,
                        state="pending",
                        deployed_generation=state.deployed.get(bundle.name, 0),
                        digest=bundle.digest,
                        hot_digest=bundle.hot_digest,
                        simulated=bundle.simulated,
                    )
                )
        return reply

    # -- world ----------------------------------------------------------------------------------

    def _handle_world(self, query):
        """The world's whole status file (trails, lidar hits, obstacles), for `fleet snapshot`."""
        request = _request_on_its_key(_payload(query), query.key_expr, p.WorldRequest)
        yield p.world_key(request.fleet, self.name), p.encode(self.world_reply(request.fleet))

    def world_reply(self, fleet: str) -> p.WorldReply:
        """The state of the fleet's world running here; ProtocolError when there is none to give."""
        with self._lock:
            worlds = [u for (f, _), u in self._units.items() if f == fleet and u.bundle.kind == "world"]
        if not worlds:
            raise p.ProtocolError(f"agent {self.name} runs no world of fleet {fleet!r}", "not_found")
        data = worlds[0].world_file()
        if data is None:
            raise p.ProtocolError(
                f"the world of fleet {fleet!r} has not reported its state yet "
                f"(starting, or not running: see `fleet logs world`)",
                "not_ready",  # not the asker's mistake: asked again later, it has one
            )
        try:
            document = p.world_document(data)
        except ValueError as error:
            raise p.ProtocolError(f"the world's status file is invalid: {error}", "agent_error") from None
        return p.WorldReply(fleet=fleet, agent=self.name, world=document)

    # -- logs -----------------------------------------------------------------------------------

    def _handle_logs(self, query):
        request = _request_on_its_key(_payload(query), query.key_expr, p.LogsRequest)
        unit = self._unit(request.fleet, request.robot)
        states = unit.node_states()
        names = [state.name for state in states]
        if request.node and request.node not in names and request.node not in (request.cursor or {}):
            raise _no_such_node(request.robot, request.node, unit)  # (one followed may be restarting)
        loggers = {state.name: logger_name(state.fqn) for state in states if state.fqn}
        reply = robot_logs(names, unit.log_file, request, loggers)
        yield p.logs_key(request.fleet, self.name), p.encode(reply)

    # -- restart --------------------------------------------------------------------------------

    def _handle_restart(self, query):
        """Have the reconcile thread, which alone starts and stops units, stop the unit and start
        it again as it is deployed; answer at once with the number of this restart."""
        request = _request_on_its_key(_payload(query), query.key_expr, p.RestartRequest)
        self._unit(request.fleet, request.robot)  # not_found for a unit not here
        key = (request.fleet, request.robot)
        with self._lock:
            number = self._restarts_asked[key] = self._restarts_asked.get(key, 0) + 1
            self._restarts_due.add(key)
        log.info("fleet %s: restarting %s, as asked", request.fleet, request.robot)
        self._work.put(request.fleet)
        yield (
            p.restart_key(request.fleet, self.name),
            p.encode(p.RestartReply(restart=number, agent_started_at=self.info.started_at)),
        )

    def _unit(self, fleet: str, robot: str) -> Unit:
        with self._lock:
            unit = self._units.get((fleet, robot))
        if unit is None:
            raise p.ProtocolError(f"robot {robot!r} of fleet {fleet!r} does not run on agent {self.name}", "not_found")
        return unit

    # -- parameters -----------------------------------------------------------------------------

    def _handle_param(self, query):
        request = _request_on_its_key(_payload(query), query.key_expr, p.ParamRequest)
        unit = self._unit(request.fleet, request.robot)
        # fqn -> node name of the node asked for (by name or fqn), or of every node ("")
        nodes = {
            state.fqn: state.name
            for state in unit.node_states()
            if state.fqn and request.node in ("", state.name, state.fqn)
        }
        if request.node and not nodes:
            raise _no_such_node(request.robot, request.node, unit)
        # A node whose process does not run now (in backoff, failed) is answered for at once: its
        # parameter services would be waited for in vain, for up to PARAM_TIMEOUT.
        not_running = unit.not_running()
        down = {fqn: why for fqn, name in nodes.items() if (why := not_running.get(name))}
        if request.op == "list":
            reply = self._list_parameters(request, nodes, down, unit.env)
        elif down:
            fqn, why = next(iter(down.items()))
            reply = p.ParamReply(ok=False, reason=f"{request.robot}/{nodes[fqn]} is not running ({why})")
        else:
            fqn = next(iter(nodes))
            reply = call_parameter_service([fqn], request, unit.env)
            if not reply.ok and reply.code in p.INPUT_ERRORS:  # a name the node does not have: the asker's input
                raise p.ProtocolError(reply.reason, reply.code)
            if request.op == "set" and reply.ok:
                if why := unit.not_kept_by_file(nodes[fqn], request.name):
                    reply.note = f"set live only: {why}"
                else:
                    self._record_override(request, fqn, reply.value)
        yield p.param_key(request.fleet, self.name), p.encode(reply)

    def _list_parameters(
        self, request: p.ParamRequest, nodes: dict[str, str], down: dict[str, str], env: dict[str, str]
    ) -> p.ParamReply:
        """Every parameter of the nodes (fqn -> node name), named by node, and those set live; the
        nodes `down` (fqn -> why) are not asked, and said not to run."""
        running = sorted(fqn for fqn in nodes if fqn not in down)
        reply = call_parameter_service(running, request, env) if running else p.ParamReply(ok=True)
        reply.parameters = {nodes[fqn]: values for fqn, values in reply.parameters.items() if fqn in nodes}
        reply.unanswered = {nodes[fqn]: why for fqn, why in reply.unanswered.items() if fqn in nodes}
        reply.unanswered.update({nodes[fqn]: f"not running ({why})" for fqn, why in down.items()})
        with self._lock:
            state = self._fleets.get(request.fleet)
            live = dict(state.overrides.get(request.robot, {})) if state else {}
        reply.set_live = {nodes[fqn]: sorted(values) for fqn, values in live.items() if fqn in nodes}
        return reply

    def _record_override(self, request: p.ParamRequest, fqn: str, value: Any) -> None:
        """Keep an accepted set across restarts: persist it and rewrite the unit's params file."""
        with self._lock:
            state = self._fleets.get(request.fleet)
            if state is None:
                return
            robot = state.overrides.setdefault(request.robot, {})
            robot.setdefault(fqn, {})[request.name] = value
            self.store.save(state)
            overrides = {fqn_: dict(values) for fqn_, values in robot.items()}
            unit = self._units.get((request.fleet, request.robot))
        if unit is not None:
            unit.write_files(overrides)


def _shared_topics(report: dict[str, Any] | None) -> list[p.SharedTopicState]:
    """The shared topics' publishers as the watch last counted them (none before it has)."""
    if report is None:
        return []
    try:
        age = round(max(0.0, time.time() - float(report["wall_time"])), 1)
        return [p.SharedTopicState(name=name, age=age, **counts) for name, counts in report["topics"].items()]
    except (ValueError, KeyError, TypeError, AttributeError):
        return []


@dataclass(frozen=True)
class GraphReport:
    """The ROS graph as a fleet's watch last reported it."""

    written: float  # when (time.time())
    settled: bool  # it had watched for GRAPH_SETTLE: a node it does not name is absent
    nodes: frozenset[str]  # full names


def _graph_report(report: dict[str, Any] | None) -> GraphReport | None:
    """What the watch last wrote of the graph; None unless it wrote in the last WATCH_FRESH
    seconds (a watch stuck or stopped says nothing of the graph now)."""
    if report is None:
        return None
    try:
        now, written = time.time(), float(report["wall_time"])
        if now - written > WATCH_FRESH:
            return None
        settled = now - float(report["started"]) >= GRAPH_SETTLE
        return GraphReport(written, settled, frozenset(str(name) for name in report["nodes"]))
    except (ValueError, KeyError, TypeError):
        return None


def _seen_in_graph(node: p.NodeState, graph: GraphReport) -> bool | None:
    """Whether the graph has the node as its process runs now: only a report written since that
    process started counts (an older one may show its previous process's entry, as a restarted
    node's would be for up to a watch period).  A watch still learning the graph names the nodes
    it has found; of one it has not, it says nothing (None) until it has settled."""
    started = time.time() - (node.uptime or 0.0)
    if graph.written > started and node.fqn in graph.nodes:
        return True
    return False if graph.settled else None


FleetRequest = TypeVar("FleetRequest", p.ApplyRequest, p.WorldRequest, p.LogsRequest, p.RestartRequest, p.ParamRequest)


def _request_on_its_key(payload: bytes | None, key, model: type[FleetRequest]) -> FleetRequest:
    """Decode a request about one fleet, refused unless it came on that fleet's key: the router's
    access rules allow a client a fleet's keys (docs/control-plane.md), not what the body names."""
    request = p.decode(payload, model)
    if p.fleet_of_key(key) != request.fleet:
        raise p.ProtocolError(f"{request.kind} for fleet {request.fleet!r} sent on {key}", "invalid")
    return request


def _payload(query) -> bytes | None:
    payload = query.payload
    return None if payload is None else payload.to_bytes()


def _no_such_node(robot: str, node: str, unit: Unit) -> p.ProtocolError:
    return p.ProtocolError(f"robot {robot} has no node {node!r} (nodes: {', '.join(unit.node_names())})", "not_found")


def call_parameter_service(fqns: list[str], request: p.ParamRequest, env: dict[str, str]) -> p.ParamReply:
    """Run the rclpy helper in a subprocess (rclpy must not share the agent's process): a get or
    set on the one node of `fqns`, or a list of every node's parameters."""
    import json

    command = [sys.executable, "-m", "fleet.runtime.param_helper", request.op, *fqns]
    if request.op != "list":
        command.append(request.name)
    # The value goes on stdin: on the command line, a long one (a URDF for robot_description, whose
    # every quote JSON escapes) passed the CLI's limit of 128 KiB per argument and failed the exec.
    value = json.dumps(request.value) if request.op == "set" else ""
    try:
        done = subprocess.run(command, input=value, env=env, capture_output=True, text=True, timeout=p.PARAM_TIMEOUT)
    except subprocess.TimeoutExpired:
        return p.ParamReply(ok=False, reason=f"no answer from {', '.join(fqns)} within {p.PARAM_TIMEOUT:.0f} s")
    try:
        return p.ParamReply.model_validate_json(done.stdout.strip().splitlines()[-1])
    except Exception:
        reason = (done.stderr.strip().splitlines() or ["parameter helper failed"])[-1]
        return p.ParamReply(ok=False, reason=reason)


def available_backends() -> list[str]:
    backends = ["embedded"]
    if shutil.which("ros2"):
        backends.append("ros2-launch")
    return backends


def stop_leftover_processes(state_dir: Path) -> int:
    """Processes left by a previous run of this agent (found by their environment marker)."""
    from fleet.runtime.processes import processes_marked, terminate

    leftovers = processes_marked(str(state_dir), UNIT_MARKER)
    if leftovers:
        log.warning("stopping %d processes left from a previous run", len(leftovers))
        terminate(leftovers)
    return len(leftovers)
