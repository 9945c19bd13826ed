"""A fleet brought up for a test, and the handle a test drives it with.

    with running_fleet("fleets/two_robots.yaml") as fleet:
        fleet.wait_for(lambda: fleet.pose("robot1").x > 0.5, sim_timeout=10, what="robot1 drives off")

`running_fleet` (or the pytest fixture `fleet_up`, see plugin.py) gives the fleet a place of its
own on the machine: a reserved ROS domain (the spec's `ros.domain_id` is replaced), a router on
a free loopback port, one `fleet agent` process per agent the spec uses, and every state
directory and log under one directory.  It deploys through the control plane like `fleet
deploy` does, waits until every robot and the world run, and afterwards stops the agents (which
stop their robots), the router, and then kills anything still carrying the fleet's environment
marker, which it reports as a leak.
"""

from __future__ import annotations

import importlib
import math
import os
import shutil
import signal
import sys
import tempfile
import time
import uuid
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleet.rules import WORLD_STATUS_FILE, WORLD_UNIT, hosts_root, unit_dir, unit_log_dir
from fleet.testing.control_plane import ROUTER, ControlPlane, agent_key, child_environment
from fleet.testing.isolation import reserve_domain_id, with_domain_id
from fleet.testing.poll import WaitTimeout, poll
from fleet.testing.processes import MARKER_VARIABLE, processes_marked, terminate

if TYPE_CHECKING:
    from fleet.testing.ros import RosProbe

WORLD = WORLD_UNIT
WALL_PER_SIM = 3.0  # default wall-clock allowance per second of sim time a wait may take
WALL_SLACK = 20.0

# Handles not closed yet: the pytest plugin attaches their status, logs and a snapshot to a
# failing test's report.
OPEN_HANDLES: weakref.WeakSet[FleetHandle] = weakref.WeakSet()


# A wait_for condition that did not hold in time: poll's failure, by the name fleet.testing exports.
FleetTimeout = WaitTimeout


class UnknownRobot(KeyError):
    """A robot name the fleet does not have (a typo, say): raised wherever a robot is named, so
    `assert not fleet.contacts("alhpa")` cannot pass by looking at nobody."""

    def __str__(self) -> str:
        return str(self.args[0])  # KeyError would show the message quoted


class NotSimulated(LookupError):
    """A robot the world does not host (a real one, `simulated: false`, or any robot of a fleet
    without a world) was asked for what only the world knows: its pose, velocity, battery or
    contacts.  Waiting does not change that, so wait_for fails at once on it."""


class FleetLeak(AssertionError):
    """Processes of the fleet were still alive after it was stopped (they were killed)."""


@dataclass(frozen=True)
class Pose:
    """A robot's pose in the shared world frame: m, m, rad."""

    x: float
    y: float
    yaw: float

    def distance_to(self, other: Pose | tuple[float, float]) -> float:
        ox, oy = (other.x, other.y) if isinstance(other, Pose) else other
        return math.hypot(self.x - ox, self.y - oy)


class FleetHandle:
    """One isolated fleet: start(), drive it from a test, close()."""

    def __init__(self, spec: str | Path | Any, directory: str | Path, sets: list[str] | tuple[str, ...] = ()):
        self.root = Path(directory).resolve()
        self.root.mkdir(parents=True, exist_ok=True)
        self._reservation = reserve_domain_id()
        self.domain_id = self._reservation.domain_id
        self.marker = f"fleet-{uuid.uuid4().hex[:12]}"
        self.env = child_environment(MARKER_VARIABLE, self.marker, self.root / "state")
        self.control = ControlPlane(self.root, self.env)
        self.spec_source = spec
        self.sets = list(sets)
        try:
            self.spec, self.expansion = self._expand(spec, self.sets)
        except BaseException:  # a bad spec: nothing started, give the domain back
            self._reservation.release()
            raise
        self.generation = 0
        self._probe: RosProbe | None = None
        self.discovery_server: str | None = None  # "address:port" of the fleet's, once deployed
        self._closed = False
        self._started_agents: set[str] = set()  # ever started, killed ones included

    # -- life cycle -----------------------------------------------------------------------------

    @property
    def name(self) -> str:
        return self.expansion.fleet

    @property
    def endpoint(self) -> str:
        return self.control.endpoint

    def start(self, timeout: float = 120.0) -> FleetHandle:
        OPEN_HANDLES.add(self)
        self.control.start_router()
        for agent in self.agents():
            self.start_agent(agent)
        outcome = self.deploy(timeout=timeout, check=False)
        if not outcome.ok:
            raise AssertionError(
                f"fleet {self.name} did not come up: {_outcome_problem(outcome)}\n" + self.report_text()
            )
        self.wait_desired_state(timeout=timeout)
        return self

    def close(self, check_leaks: bool = True) -> None:
        """Stop everything; raise FleetLeak if processes had to be killed after a clean stop."""
        if self._closed:
            return
        self._closed = True
        OPEN_HANDLES.discard(self)
        described: list[str] = []
        try:
            if self._probe is not None:
                self._probe.close()
                self._probe = None
            self.control.stop()
        finally:
            from fleet.runtime.hosting import remove_orphaned_socket_dirs

            for agent in self._started_agents:  # one killed (by a test, or by stop) left its hosts' sockets
                remove_orphaned_socket_dirs(hosts_root(self.control.agent_dir(agent)))
            leftovers = processes_marked(self.marker)
            described = [_describe(process) for process in leftovers]
            if leftovers:
                terminate(leftovers)
                described += [f"still alive after SIGKILL: {_describe(p)}" for p in processes_marked(self.marker)]
            self._reservation.release()
        if described and check_leaks:
            raise FleetLeak(
                f"fleet {self.name}: {len(described)} process(es) outlived the clean stop and were killed:\n"
                + "\n".join([*described, *self.control.forced])
            )

    def robots(self) -> list[str]:
        """The robots of the current spec."""
        return [robot.name for robot in self.spec.robots]

    def _known(self, robot: str, world: bool = False) -> str:
        """`robot`, if the fleet has it (or it is the world, where `world` allows it)."""
        names = self.robots() + ([WORLD] if world and self.expansion.bundle(WORLD) is not None else [])
        if robot not in names:
            raise UnknownRobot(f"fleet {self.name} has no robot {robot!r}; it has: {', '.join(names)}")
        return robot

    def agents(self) -> list[str]:
        """The agents the current spec places robots (or the world) on."""
        return sorted({bundle.agent for bundle in self.expansion.bundles})

    # -- deploying ------------------------------------------------------------------------------

    def _expand(self, spec, sets):
        from fleet.expand import expand_fleet
        from fleet.spec import FleetSpec, load_spec

        loaded = spec if isinstance(spec, FleetSpec) else load_spec(Path(spec))
        isolated = with_domain_id(loaded, self.domain_id)
        return isolated, expand_fleet(isolated, list(sets))

    def deploy(
        self,
        spec: str | Path | Any | None = None,
        sets: list[str] | tuple[str, ...] | None = None,
        timeout: float = 90.0,
        check: bool = True,
    ):
        """Deploy (again): a changed spec and/or other `--set` overrides (default: the current
        ones).  Agents the spec newly uses are started first (not those a test stopped: a deploy
        meets them down, as it would in the field).  Returns fleet.client.deployment's
        Outcome; with check=True a deploy that did not bring every robot up fails the test."""
        from fleet.client import deploy

        if spec is not None or sets is not None:
            self.spec_source = spec if spec is not None else self.spec_source
            self.sets = list(sets) if sets is not None else self.sets
            self.spec, self.expansion = self._expand(self.spec_source, self.sets)
        for agent in self.agents():
            if agent not in self._started_agents:
                self.start_agent(agent)
        self._wait_agents_online(self.control.running_agents() & set(self.agents()))
        with self.control.client() as client:
            outcome = deploy(client, self.expansion, wait=True, timeout=timeout)
        self.generation = outcome.generation
        if outcome.discovery is not None and outcome.discovery.server:
            self.discovery_server = outcome.discovery.server
        if check and not outcome.ok:
            raise AssertionError(
                f"deploy of fleet {self.name} failed: {_outcome_problem(outcome)}\n" + self.report_text()
            )
        return outcome

    def _wait_agents_online(self, names: set[str], timeout: float = 30.0) -> None:
        """Agents just started take a moment to connect; a deploy must not find them unreachable.
        (Agents a test killed are not running, so a deploy meets them down, as it should.)"""

        def online() -> set[str]:
            return {row.name for row in self.status().agents if row.online}

        self.wait_for(
            lambda: names <= online(),
            timeout=timeout,
            what=f"agents {', '.join(sorted(names))} online",
            explain=lambda: "\n".join(self.control.log_tail(agent_key(n), 10) for n in sorted(names)),
        )

    # -- status ---------------------------------------------------------------------------------

    def status(self):
        """This fleet's part of `fleet status` (a fleet.plan.view.FleetView)."""
        from fleet.plan import build_view

        with self.control.client() as client:
            view = build_view(*client.status(self.name), time.time())
        return view.only(self.name)

    def robot_status(self, robot: str):
        """The status row (fleet.plan.view.RobotRow) of a robot, or of `world`."""
        self._known(robot, world=True)
        rows = self.status().find_robot(robot)
        if not rows:
            raise KeyError(f"fleet {self.name} has no robot {robot!r} in status")
        return rows[0]

    def pids(self, robot: str) -> set[int]:
        return self.robot_status(robot).pids

    def node_pid(self, robot: str, node: str) -> int:
        for entry in self.robot_status(robot).nodes:
            if node in (entry.get("name"), entry.get("fqn")) and entry.get("pid"):
                return entry["pid"]
        raise KeyError(f"node {node!r} of {robot} is not running")

    def desired_state_problems(self) -> list[str]:
        """What keeps the fleet from its desired state now (empty: every bundle of the last deploy
        runs all its nodes at that generation, and the world hosts every simulated robot)."""
        try:
            view = self.status()
        except Exception as error:
            return [f"status unavailable: {error}"]
        rows = {row.name: row for row in view.robots}
        problems = []
        for bundle in self.expansion.bundles:
            row = rows.pop(bundle.name, None)
            if row is None:
                problems.append(f"{bundle.name}: not in status")
            elif row.agent != bundle.agent:
                problems.append(f"{bundle.name}: on agent {row.agent}, wanted {bundle.agent}")
            elif row.state != "running" or row.running != row.total or row.total == 0:
                problems.append(f"{bundle.name}: {row.state} ({row.running}/{row.total} nodes) {row.error}".rstrip())
            elif row.generation < self.generation or row.digest != bundle.digest:
                problems.append(f"{bundle.name}: runs generation {row.generation}, wanted {self.generation}")
        problems += [f"{name}: running but not in the spec" for name, row in rows.items() if row.state != "offline"]
        if self.spec.world is not None:
            world = self.world()
            if world is None:
                problems.append("world: no status file yet")
            else:
                missing = sorted(set(self.simulated_robots()) - set(world.get("robots", {})))
                if missing:
                    problems.append(f"world: robots not spawned: {', '.join(missing)}")
                if time.time() - world.get("wall_time", 0) > 3.0:
                    problems.append("world: status file not updated for 3 s")
        return problems

    def wait_desired_state(self, timeout: float = 60.0):
        """Wait (wall time) until desired_state_problems() is empty; returns the status view."""
        __tracebackhide__ = True
        self.wait_for(
            lambda: not self.desired_state_problems(),
            timeout=timeout,
            what=f"fleet {self.name} to reach its desired state",
            explain=lambda: "; ".join(self.desired_state_problems()),
        )
        return self.status()

    # -- the world ------------------------------------------------------------------------------

    def simulated_robots(self) -> list[str]:
        if self.spec.world is None:
            return []
        return [robot.name for robot in self.spec.robots if robot.simulated]

    def world_status_file(self) -> Path | None:
        bundle = self.expansion.bundle(WORLD)
        if bundle is None:
            return None
        # The agent's documented layout: <state-dir>/units/<fleet>/<unit>/ (docs/control-plane.md)
        return unit_dir(self.control.agent_dir(bundle.agent), self.name, WORLD) / WORLD_STATUS_FILE

    def world(self) -> dict[str, Any] | None:
        """The world's full status document (sim_time, robots with pose/velocity/battery/trail,
        obstacles, contacts, errors), or None before the world wrote it."""
        from fleet.world.status import read_status

        path = self.world_status_file()
        return read_status(path) if path is not None else None

    def _world(self) -> dict[str, Any]:
        world = self.world()
        if world is None:
            raise KeyError(f"fleet {self.name} has no world status yet")
        return world

    def sim_time(self) -> float:
        return float(self._world()["sim_time"])

    def _hosted(self, robot: str) -> str:
        """`robot`, if the world hosts it: a real robot has no pose, speed or contacts there."""
        if self._known(robot) not in self.simulated_robots():
            why = "it is real (simulated: false)" if self.spec.world is not None else "the fleet has no world"
            raise NotSimulated(
                f"fleet {self.name}: the world does not host robot {robot!r} ({why}), so it has no pose, "
                f"velocity, battery or contacts there; read its own topics instead (subscribe({robot!r}, 'odom'))"
            )
        return robot

    def _in_world(self, robot: str) -> dict[str, Any]:
        entry = self._world()["robots"].get(self._hosted(robot))
        if entry is None:  # not spawned yet: wait_for waits on
            raise KeyError(f"the world of fleet {self.name} does not host {robot} yet")
        return entry

    def pose(self, robot: str) -> Pose:
        entry = self._in_world(robot)["pose"]
        return Pose(entry["x"], entry["y"], entry["yaw"])

    def velocity(self, robot: str) -> tuple[float, float]:
        """(linear m/s, angular rad/s) of a robot as the world simulates it."""
        entry = self._in_world(robot)["velocity"]
        return entry["linear"], entry["angular"]

    def battery(self, robot: str) -> float | None:
        return self._in_world(robot).get("battery")

    def contacts(self, robot: str | None = None) -> list[dict[str, Any]]:
        """The world's recent contacts ({sim_time, a, b, kind}), those involving `robot` if given."""
        if robot is not None:
            self._hosted(robot)  # a real robot has none, which must not pass for "no contact"
        last = self._world().get("contacts", {}).get("last", [])
        return [c for c in last if robot is None or robot in (c.get("a"), c.get("b"))]

    def contact_count(self) -> int:
        return int(self._world().get("contacts", {}).get("count", 0))

    def snapshot(self, path: str | Path) -> Path:
        """A top-down PNG of the world now (obstacles, robots, trails, lidar hits)."""
        from fleet.world.snapshot import draw_snapshot

        return draw_snapshot(self._world(), path, title=f"fleet {self.name} at sim time {self.sim_time():.1f} s")

    # -- ROS ------------------------------------------------------------------------------------

    @property
    def ros(self):
        """A fleet.testing.ros.RosProbe in the fleet's ROS domain (created on first use)."""
        if self._probe is None:
            from fleet.testing.ros import RosProbe

            # A discovery client of the fleet's server, like the fleet's own nodes.
            self._probe = RosProbe(
                f"fleet_test_{uuid.uuid4().hex[:8]}", domain_id=self.domain_id, discovery_server=self.discovery_server
            )
        return self._probe

    def namespace(self, robot: str) -> str:
        spec = self.spec.robot(self._known(robot))
        assert spec is not None
        return (spec.namespace or f"/{robot}").rstrip("/")

    def topic(self, robot: str, name: str) -> str:
        """A robot's topic (or node) name: topic("robot1", "odom") -> "/robot1/odom"; an absolute
        name stays as it is."""
        namespace = self.namespace(robot)  # checks the robot, also for an absolute name
        return name if name.startswith("/") else f"{namespace}/{name}"

    def subscribe(self, robot: str, topic: str, message_type=None, keep: int = 1000, qos=None):
        """Collect a robot's messages (a fleet.testing.ros.Subscription: .messages, .last, .count).
        Without message_type the type is looked up in the ROS graph.  Without qos (an rclpy
        QoSProfile or a depth) the subscription takes what the topic's publishers in the graph
        offer (best effort if any is; see RosProbe.publisher_qos).  Messages arrive while the
        test waits through this handle (wait_for, wait_sim, spin)."""
        name = self.topic(robot, topic)
        if message_type is None:
            message_type = self._graph_type(name)
        return self.ros.subscribe(name, message_type, keep, qos=qos)

    def publish(self, robot: str, topic: str, message) -> None:
        """Publish on a robot's topic.  The first message on a topic waits (up to 5 s of wall
        time) until the topic's subscribers are matched with the new publisher, so it is not
        lost (see RosProbe.publish)."""
        self.ros.publish(self.topic(robot, topic), message)

    def get_param(self, robot: str, node: str, name: str) -> Any:
        """A parameter of a running node; fleet.testing.ros.NoSuchParameter if it has none of that name."""
        return self.ros.get_parameters(self.topic(robot, node), [name])[0]

    def set_param(self, robot: str, node: str, name: str, value: Any) -> tuple[bool, str]:
        """Set a parameter on the running node (like `ros2 param set`): (accepted, reason).  It
        lasts until the node restarts; `fleet param set` or a deploy with --set keep it."""
        return self.ros.set_parameter(self.topic(robot, node), name, value)

    def _graph_type(self, topic: str):
        found = self.wait_for(lambda: self.ros.topics().get(topic), timeout=15, what=f"topic {topic} in the ROS graph")
        package, _, kind = found[0].split("/")
        return getattr(importlib.import_module(f"{package}.msg"), kind)

    # -- waiting --------------------------------------------------------------------------------

    def spin(self, seconds: float) -> None:
        """Let `seconds` of wall time pass, delivering ROS messages to subscriptions meanwhile."""
        deadline = time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            self._pause(min(left, 0.05))

    def _pause(self, seconds: float) -> None:
        if self._probe is not None:
            self._probe.executor.spin_once(timeout_sec=seconds)
        else:
            time.sleep(seconds)

    def wait_for(
        self,
        condition: Callable[[], Any],
        sim_timeout: float | None = None,
        timeout: float | None = None,
        what: str | None = None,
        interval: float = 0.1,
        explain: Callable[[], str] | None = None,
    ) -> Any:
        """Poll condition() until it returns something truthy, and return that.

        sim_timeout: seconds of *simulated* time (the world's clock) it may take; timeout:
        seconds of wall time (default: WALL_PER_SIM x sim_timeout + WALL_SLACK, so a stalled
        world fails too).  An exception raised by condition() counts as "not yet" and is shown
        if time runs out.  The failure (FleetTimeout) names `what`, the sim and wall time that
        passed, the last result (and explain() when given)."""
        __tracebackhide__ = True  # pytest shows the test's line, not this loop
        if timeout is None:
            if sim_timeout is None:
                raise ValueError("wait_for needs sim_timeout or timeout")
            timeout = WALL_PER_SIM * sim_timeout + WALL_SLACK
        clock = _SimClock(self)

        def sim_time_passed() -> str:
            limit = f" (limit {sim_timeout:g})" if sim_timeout is not None else ""
            text = f"fleet {self.name}: {clock.elapsed():.1f} s of sim time{limit} passed"
            return text + (f"; {explain()}" if explain is not None else "")

        return poll(
            condition,
            timeout=timeout,
            what=what or str(getattr(condition, "__name__", "condition")),
            interval=interval,
            pause=self._pause,
            retry_on=(Exception,),  # not ready yet (a robot not spawned, the router away, ...)
            give_up_on=(UnknownRobot, NotSimulated),  # but no wait brings a robot the fleet lacks
            expired=(lambda: clock.elapsed() >= sim_timeout) if sim_timeout is not None else None,
            explain=sim_time_passed,
        )

    def wait_sim(self, seconds: float) -> None:
        """Let `seconds` of sim time pass (subscriptions keep receiving)."""
        __tracebackhide__ = True
        clock = _SimClock(self)
        self.wait_for(
            lambda: clock.elapsed() >= seconds,
            timeout=WALL_PER_SIM * seconds + WALL_SLACK,
            what=f"{seconds:g} s of sim time to pass",
        )

    # -- faults ---------------------------------------------------------------------------------

    def kill_node(self, robot: str, node: str, signum: int = signal.SIGKILL) -> int:
        """Signal the process hosting a node; returns when its agent noticed (the pid left
        status).  Its respawn is the runner's job: follow with wait_desired_state()."""
        pid = self.node_pid(robot, node)
        os.kill(pid, signum)
        self.wait_for(lambda: pid not in self.pids(robot), timeout=20, what=f"{robot}/{node} (pid {pid}) to be gone")
        return pid

    def restart(self, *robots: str, timeout: float = 60.0, check: bool = True):
        """`fleet restart`: each robot's (or the world's) nodes stop and start again as deployed;
        returns fleet.client.deployment's Restart once each runs again.  With check=True a
        robot that did not fails the test."""
        from fleet.client import restart

        for robot in robots:
            self._known(robot, world=True)
        with self.control.client() as client:
            outcome = restart(client, list(robots), self.name, timeout=timeout)
        if check and not outcome.ok:
            rows = "; ".join(f"{row.name} {row.state} {row.reason}".strip() for row in outcome.rows.values())
            raise AssertionError(f"restart of {', '.join(robots)} failed: {rows}\n" + self.report_text())
        return outcome

    def kill_world(self, signum: int = signal.SIGKILL) -> int:
        return self.kill_node(WORLD, WORLD, signum)

    def kill_agent(self, name: str, signum: int = signal.SIGKILL) -> int:
        """Signal an agent process and wait for it to end (its robots die with it)."""
        return self.control.kill(agent_key(name), signum)

    def start_agent(self, name: str) -> None:
        """Start an agent (again, on its state directory: it restores its robots by itself)."""
        self.control.start_agent(name)
        self._started_agents.add(name)

    def restart_agent(self, name: str, signum: int = signal.SIGKILL) -> int:
        pid = self.kill_agent(name, signum)
        self.start_agent(name)
        return pid

    def kill_router(self, signum: int = signal.SIGTERM) -> int:
        return self.control.kill(ROUTER, signum)

    def start_router(self) -> None:
        """Start the router again on the same endpoint (agents reconnect by themselves)."""
        self.control.start_router()

    def restart_router(self, signum: int = signal.SIGTERM) -> int:
        pid = self.kill_router(signum)
        self.start_router()
        return pid

    def start_missing(self) -> None:
        """Start the router and every agent of the spec that is not running (after faults)."""
        if self.control.pid(ROUTER) is None:
            self.start_router()
        for agent in self.agents():
            if self.control.pid(agent_key(agent)) is None:
                self.start_agent(agent)

    def leftover_processes(self) -> list[str]:
        """Processes carrying the fleet's marker that nobody accounts for: not the router or an
        agent, not a node in status nor a child of one (the world's status writer), say an old
        world or node left by a fault."""
        import psutil

        expected = set(self.control.running().values())
        view = self.status()
        for row in view.robots:
            expected |= row.pids
        expected |= view.service_pids
        leftovers = []
        for process in processes_marked(self.marker):
            if process.pid in expected:
                continue
            try:
                if "fleet.runtime.param_helper" in " ".join(process.cmdline()):
                    continue  # an agent's short-lived parameter call
                if process.ppid() in expected:
                    continue  # part of a process in status (a world's status writer)
            except psutil.Error:
                continue
            leftovers.append(_describe(process))
        return leftovers

    def assert_no_leaks(self, timeout: float = 10.0) -> None:
        """Every process of the fleet is accounted for (processes just signalled may take a moment)."""
        __tracebackhide__ = True
        self.wait_for(
            lambda: not self.leftover_processes(),
            timeout=timeout,
            what=f"fleet {self.name} to leak nothing",
            explain=lambda: "unaccounted for: " + "; ".join(self.leftover_processes()),
        )

    # -- diagnostics ----------------------------------------------------------------------------

    def log_dir(self, robot: str) -> Path:
        """Where the agent writes the logs of a robot's (or the world's) processes.  They stay
        there after the fleet is closed (the fleet's directory is the test's), unless a deploy
        removed the robot: its agent then deletes its unit directory, logs included."""
        bundle = self.expansion.bundle(self._known(robot, world=True))
        if bundle is None:
            raise KeyError(f"fleet {self.name} runs no bundle for {robot!r}")
        return unit_log_dir(unit_dir(self.control.agent_dir(bundle.agent), self.name, robot))

    def logs(self, robot: str, lines: int = 20) -> dict[str, list[str]]:
        """The last lines of each process log of a robot (or the world), by process: a node
        hosted in a shared process (isolation `agent`) by its name ({"controller": [...]}), a
        process of its own by its launch name ({"controller-1": [...], "world-1": [...]})."""
        found = {}
        for path in sorted(self.log_dir(robot).glob("*.log")):
            found[path.stem] = path.read_text(errors="replace").splitlines()[-lines:]
        return found

    def status_table(self) -> str:
        """The fleet's status as plain text: robots, nodes with pids and restarts, desired state."""
        from fleet.testing.report import status_table

        return status_table(self)

    def failure_sections(self, snapshot_path: str | Path | None = None) -> list[tuple[str, str]]:
        """(title, text) pairs: status table, router/agent logs, node logs, world (and snapshot)."""
        from fleet.testing.report import failure_sections

        return failure_sections(self, snapshot_path)

    def report_text(self, snapshot_path: str | Path | None = None) -> str:
        return "\n\n".join(f"--- {title} ---\n{text}" for title, text in self.failure_sections(snapshot_path))


def _outcome_problem(outcome) -> str:
    parts = []
    if outcome.unreachable:
        parts.append("unreachable agents: " + ", ".join(sorted(outcome.unreachable)))
    if outcome.refused:
        parts.append("refused: " + "; ".join(f"{a}: {r}" for a, r in outcome.refused.items()))
    if outcome.superseded_by:
        parts.append(f"superseded by generation {outcome.superseded_by}")
    if outcome.timed_out:
        parts.append("timed out waiting for every robot to run")
    if outcome.view is not None:
        parts += [
            f"{row.name}: {row.state} {row.error}".rstrip() for row in outcome.view.robots if row.state != "running"
        ]
    return "; ".join(parts) or "not every robot runs"


def _describe(process) -> str:
    try:
        return f"pid {process.pid}: {' '.join(process.cmdline())[:200]}"
    except Exception:
        return f"pid {process.pid}"


class _SimClock:
    """Sim time elapsed since creation, from the world's status file.  Counts only forward
    steps, so a wait neither ends early nor hangs whatever a restarted world's clock does (it
    resumes from its last status, a little ahead after a crash); without a world (real robots)
    it is wall time."""

    def __init__(self, fleet: FleetHandle):
        self.fleet = fleet
        self.has_world = fleet.world_status_file() is not None
        self.last = self._now()
        self.total = 0.0
        self.wall_start = time.monotonic()

    def _now(self) -> float | None:
        try:
            return self.fleet.sim_time()
        except (KeyError, TypeError, ValueError):
            return None

    def elapsed(self) -> float:
        if not self.has_world:
            return time.monotonic() - self.wall_start
        now = self._now()
        if now is not None:
            if self.last is not None and now > self.last:
                self.total += now - self.last
            self.last = now
        return self.total


@contextmanager
def running_fleet(
    spec: str | Path | Any,
    sets: list[str] | tuple[str, ...] = (),
    directory: str | Path | None = None,
    timeout: float = 120.0,
    check_leaks: bool = True,
) -> Iterator[FleetHandle]:
    """Bring a fleet up from a spec (a YAML path or a FleetSpec), isolated from everything else
    on this machine; yield its FleetHandle; tear it all down afterwards, also on failure.  When
    the body raises, the fleet's status, node logs and a world snapshot are printed to stderr.

    Without `directory`, the fleet's files go to a new temporary directory, removed once the
    fleet ended cleanly (a script run again and again would fill /tmp with them) and kept, for
    its logs, when anything failed."""
    own_directory = directory is None
    directory = Path(directory) if directory is not None else Path(tempfile.mkdtemp(prefix="fleet-test-"))
    try:
        handle = FleetHandle(spec, directory, sets)
    except BaseException:  # a bad spec: nothing ran, so nothing is worth keeping
        if own_directory:
            shutil.rmtree(directory, ignore_errors=True)
        raise
    try:
        handle.start(timeout)
        yield handle
    except BaseException as error:
        if not isinstance(error, (KeyboardInterrupt, GeneratorExit)) and handle.generation:
            try:
                print(handle.report_text(directory / "failure.png"), file=sys.stderr)
            except Exception as report_error:  # never hide the test's own failure
                print(f"(fleet failure report unavailable: {report_error})", file=sys.stderr)
        handle.close(check_leaks=False)
        raise
    handle.close(check_leaks=check_leaks)  # a leak raises here, keeping the directory too
    if own_directory:
        shutil.rmtree(directory, ignore_errors=True)
