"""A unit: one bundle (a robot or the world) written to disk and run by the embedded runner.

The agent owns units; a unit owns one fleet.runtime LaunchSession.  Every process a unit starts
carries UNIT_MARKER in its environment, so the agent (at start-up) and its reaper (when the
agent dies, even by SIGKILL) find and stop them without trusting pid files: pids are reused,
and respawned nodes get new ones.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from fleet.errors import FleetError, Location, SpecError
from fleet.files import write_atomic
from fleet.launchfile.reader import read_launch_file
from fleet.rules import PARAMS_SUFFIX, WORLD_STATUS_FILE, unit_log_dir
from fleet.runtime.launch_file import check_bundle_launch
from fleet.runtime.supervisor import BACKOFF, EXITED, FAILED, RUNNING, STARTING, LaunchSession, NodeStatus
from fleet.spec.rcl_types import value_text
from fleet.spec.yaml_source import safe_load
from fleet.wire.protocol import (
    BundleMessage,
    NodeState,
    RobotState,
    RobotStateName,
    WorldSummary,
    check_file_name,
    world_summary,
)

UNIT_MARKER = "FLEET_AGENT_HOME"  # value: the agent's state directory

if TYPE_CHECKING:
    from fleet.runtime.hosting import HostPool


def launch_session(bundle: BundleMessage, directory: Path, env: dict[str, str]) -> LaunchSession:
    """The session that runs the bundle whose files are in `directory` (not started)."""
    from fleet.runtime.supervisor import LaunchSession

    isolation = str(bundle.options.get("isolation", "process"))
    return LaunchSession(directory / bundle.entry, {}, env, unit_log_dir(directory), isolation, backend="auto")


def launch_problem(bundle: BundleMessage, env: dict[str, str]) -> str | None:
    """Why this bundle's unit could not start on this computer (its launch file names a package,
    an executable or a file that is not here, ...), None if it could.  `fleet deploy` asks every
    agent this before it changes anything, so a bad template leaves the robots running as they
    were.  The files go to a scratch directory named after the robot: the problem then reads
    robot1/robot1.launch.yaml:LINE:COL, where `fleet render -o DIR` writes that file."""
    with tempfile.TemporaryDirectory(prefix="fleet-check-") as scratch:
        directory = Path(scratch) / bundle.name
        directory.mkdir()
        for name, text in bundle.files.items():
            (directory / check_file_name(name)).write_text(text)
        try:
            launch_session(bundle, directory, env).check()
        except FleetError as error:  # whole: the CLI makes it one line, once
            problem = error.message if error.location is None else f"{error.location}: {error.message}"
            return problem.replace(f"{scratch}/", "")
    return None


class Unit:
    def __init__(
        self,
        fleet: str,
        bundle: BundleMessage,
        directory: Path,
        env: dict[str, str],
        hosts: HostPool | None = None,  # where its fleet nodes run under isolation: agent
    ):
        self.fleet = fleet
        self.hosts = hosts
        self.hosted = False  # its fleet nodes are in self.hosts
        self.bundle = bundle
        self.directory = directory
        self.env = env
        self.generation = 0  # of the desired state it was last reconciled to
        self.deployed_generation = 0  # of the deploy that brought the description it runs
        self.restarted = 0  # the `fleet restart`s of it carried out before it started
        self.session: LaunchSession | None = None
        self.error = ""
        self.seen_running = False

    @property
    def name(self) -> str:
        return self.bundle.name

    @property
    def log_dir(self) -> Path:
        return unit_log_dir(self.directory)

    # -- files ----------------------------------------------------------------------------------

    def write_files(self, overrides: dict[str, dict[str, Any]], names: set[str] | None = None) -> None:
        """Write the bundle's files (live parameter overrides merged into its params files)."""
        self.directory.mkdir(parents=True, exist_ok=True)
        files = with_overrides(self.bundle.files, overrides)
        for name, text in files.items():
            if names is not None and name not in names:
                continue
            path = self.directory / check_file_name(name)
            if path.resolve().parent != self.directory.resolve():  # defence in depth
                raise ValueError(f"file {name!r} escapes the unit directory")
            write_atomic(path, text, durable=True)

    def hot_update(self, bundle: BundleMessage, overrides: dict[str, dict[str, Any]]) -> None:
        """Files such as world.yaml are re-read by the running process: rewrite them in place.
        Files that cannot be written fail the unit, as at its start (the next apply starts it
        again): its processes would run on files that are neither the old nor the new ones."""
        previous, self.bundle = self.bundle, bundle
        try:
            self.write_files(overrides, names=set(bundle.hot_files))
        except OSError as error:
            self.bundle = previous  # its status says what it last ran, not what it was to run
            self.error = f"cannot write its files: {error}"
            self.stop()

    # -- processes ------------------------------------------------------------------------------

    def start(self, overrides: dict[str, dict[str, Any]]) -> None:
        self.error = ""
        self.seen_running = False
        try:
            self.write_files(overrides)
            self.log_dir.mkdir(parents=True, exist_ok=True)
            self.session = launch_session(self.bundle, self.directory, self.env)
            self.session.start()
            hosted = self.session.hosted_nodes()
            if hosted:
                if self.hosts is None:
                    raise ValueError("isolation 'agent' needs the agent's host processes")
                self.hosts.add_robot(self.name, hosted, self.log_dir)
                self.hosted = True
        except Exception as error:  # a bad bundle fails this unit, never the agent
            self.error = str(error) or type(error).__name__
            self.stop()

    def stop(self) -> None:
        session, self.session = self.session, None
        if self.hosted and self.hosts is not None:
            self.hosted = False
            self.hosts.remove_robot(self.name)
        if session is not None:
            session.stop()

    # -- reporting ------------------------------------------------------------------------------

    def node_states(self) -> list[NodeState]:
        return [_wire(node) for node in self._node_statuses()]

    def _node_statuses(self) -> list[NodeStatus]:
        if self.session is None:
            return []
        hosted = self.hosts.node_status(self.name) if self.hosted and self.hosts is not None else []
        return [*hosted, *self.session.status()]

    def state(self, overrides: dict[str, dict[str, Any]]) -> RobotState:
        statuses = self._node_statuses()
        nodes = [_wire(node) for node in statuses]
        running = sum(1 for node in nodes if node.state == RUNNING)
        total = len(nodes)
        state: RobotStateName
        if self.error:
            state = "failed"
        elif self.session is None:
            state = "stopped"
        elif total and running == total:
            state = "running"
            self.seen_running = True
        elif any(node.state in (FAILED, "error") for node in nodes):
            state = "failed"
        elif self.seen_running or any(node.state in (BACKOFF, EXITED) for node in nodes):
            # A node that ended is not coming up: it was restarted (and may end again) or is gone.
            state = "degraded"
        else:
            state = "starting"
        return RobotState(
            name=self.name,
            kind=self.bundle.kind,
            state=state,
            reason=next((node.problem for node in statuses if node.state != RUNNING and node.problem), ""),
            nodes=nodes,
            running=running,
            total=total,
            # Per process: the nodes sharing one (composite, a host's robot) restart together.
            restarts=sum({node.process: node.restarts for node in statuses}.values()),
            generation=self.generation,
            deployed_generation=self.deployed_generation,
            digest=self.bundle.digest,
            hot_digest=self.bundle.hot_digest,
            overrides=overrides,
            error=self.error,
            restarted=self.restarted,
            simulated=self.bundle.simulated,
        )

    def world_file(self) -> dict[str, Any] | None:
        """The world's status file as its running process wrote it (None: not the world, or
        nothing readable from this process yet).

        The world writes it atomically, so a read never sees half of one."""
        from fleet.world.status import read_status, written_since

        if self.bundle.kind != "world":
            return None
        data = read_status(self.directory / WORLD_STATUS_FILE)
        if data is None or not written_since(data, self._started_at()):
            return None
        return data

    def _started_at(self) -> float | None:
        """Wall time the unit's oldest running process started (None: none runs)."""
        uptimes = [node.uptime for node in self.node_states() if node.state == RUNNING and node.uptime]
        return time.time() - max(uptimes) if uptimes else None

    def world_summary(self) -> WorldSummary | None:
        """What a status reply carries of the world: no trails, no scan hits, the last few contacts.
        An invalid file (someone edited it) is left out rather than failing the whole status."""
        data = self.world_file()
        if data is None:
            return None
        try:
            summary = world_summary(data)
        except ValueError:
            return None
        wall_time = data.get("wall_time")
        if isinstance(wall_time, (int, float)):  # written on this computer: same clock
            summary.age = round(max(0.0, time.time() - wall_time), 2)
        return summary

    def not_kept_by_file(self, node: str, name: str) -> str | None:
        """Why a value set live on `node`'s parameter `name` would not come back from the robot's
        parameter file when the node restarts: the launch file gives the parameter inline after the
        file, or starts the node without the file.  None when it would come back."""
        params_files = frozenset(file for file in self.bundle.files if file.endswith(PARAMS_SUFFIX))
        try:
            description = read_launch_file(self.directory / self.bundle.entry)
            inline, without_file = check_bundle_launch(description, frozenset(self.bundle.files), params_files)
        except FleetError:  # a file it could not read: it runs no launch file of ours to ask
            return None
        if found := inline.get(node, {}).get(name):
            where = " after the parameter file" if node not in without_file else ""
            return (
                f"the launch file gives {name} inline{where} ({_file_place(found.where)}: "
                f"{value_text(found.value)}), so a restart brings that value back"
            )
        if node in without_file:
            return (
                f"the launch file starts {node} without the robot's parameter file "
                f"({_file_place(without_file[node])}), so a restart brings the node's own default back"
            )
        return None

    def not_running(self) -> dict[str, str]:
        """Its nodes whose process does not run now (named as node_states names them), each with
        why: its state and how its process ended (`backoff: controller exited with code 2 ...`).
        A node still starting is not among them: its services are about to be there."""
        return {
            _wire(node).name: f"{node.state}: {node.problem}" if node.problem else node.state
            for node in self._node_statuses()
            if node.state not in (RUNNING, STARTING)
        }

    def node_names(self) -> list[str]:
        return [state.name for state in self.node_states()]

    def log_file(self, node: str) -> Path | None:
        """The log file of the process hosting `node` (the runner keeps one per process; a host
        process of isolation: agent one per hosted node)."""
        if self.session is None:
            return None
        if self.hosted and self.hosts is not None:
            path = self.hosts.log_file(self.name, node)
            if path is not None:
                return path
        try:
            return self.session.log_file(node)
        except KeyError:
            return None


def _wire(node: NodeStatus) -> NodeState:
    return NodeState(
        # fleet's launch files name every node (fleet.expand.outline); a plain executable has no
        # node name, and its process's (`sleep-1`, as launch names it) stands for it
        name=node.name or node.process,
        fqn=node.fqn or "",
        state=str(node.state),
        pid=node.pid,
        restarts=node.restarts or 0,
        exit_code=node.exit_code,
        uptime=node.uptime,
        ros=node.ros,
    )


def with_overrides(files: dict[str, str], overrides: dict[str, dict[str, Any]]) -> dict[str, str]:
    """Merge live overrides (node fqn -> parameter -> value) into the ROS params files."""
    if not overrides:
        return dict(files)
    result = dict(files)
    pending = {fqn: dict(values) for fqn, values in overrides.items() if values}
    params_files = []
    for name, text in files.items():
        if not name.endswith((".yaml", ".yml")):
            continue
        try:
            data = safe_load(text, name)  # from a message: the limits of every input (alias bombs...)
        except SpecError:
            continue
        if not isinstance(data, dict) or not any(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
            continue
        params_files.append(name)
        changed = False
        for fqn in list(pending):
            section = data.get(fqn)
            if isinstance(section, dict) and isinstance(section.get("ros__parameters"), dict):
                for parameter, value in pending.pop(fqn).items():
                    _put_parameter(section["ros__parameters"], parameter, value)
                changed = True
        if changed:
            result[name] = _dump_params(data)
    if pending and params_files:  # nodes without a section yet: add one to the first params file
        data = safe_load(result[params_files[0]], params_files[0])
        for fqn, values in pending.items():
            data[fqn] = {"ros__parameters": values}
        result[params_files[0]] = _dump_params(data)
    return result


def _put_parameter(parameters: dict[str, Any], name: str, value: Any) -> None:
    """Set parameter `name` (dotted, as ROS names it: `pid.kp`) where the file already writes it,
    nested (`pid: {kp: ...}`) or dotted: a second key for it beside the first would be one
    parameter written twice, which render refuses in a spec and rcl settles by order alone."""
    tokens = name.split(".")
    level = parameters
    for depth, token in enumerate(tokens):
        rest = ".".join(tokens[depth:])
        if rest in level or not isinstance(level.get(token), dict):
            level[rest] = value
            return
        level = level[token]  # the last token is always set above: `rest` is that token


def _dump_params(data: dict) -> str:
    header = f"# rewritten by the fleet agent at {time.strftime('%Y-%m-%d %H:%M:%S')}: live overrides merged\n"
    # fleet's own writer, not yaml.safe_dump: that one writes the string "1e-3" bare, which rcl
    # reads as a double (and "inf" as infinity).  Imported here: the package fleet.expand brings
    # the template machinery, which an agent needs only to write this.
    from fleet.expand import yaml_emit

    return header + yaml_emit.emit(data)


def _file_place(where: Location | None) -> str:
    """A place in a unit's launch file, by the file's name (the agent's directory is its own)."""
    if where is None:
        return "its launch file"
    return str(Location(Path(str(where.file)).name, where.line, where.column))
