"""Host processes of an agent (isolation: agent): many robots' fleet nodes in few rclpy processes.

A HostPool holds the host processes (fleet.nodes.host) of one fleet on one agent; each hosts up
to group_size robots, so one DDS participant and one rclpy runtime serve them all.  A robot is
placed in the first host with room (a new host when all are full) and stays there: adding,
restarting or removing a robot is a request to its host over the host's control channel (a
Unix socket, JSON lines), and no other robot notices.  A host that dies is started again with
its robots, each of which counts a restart.

Every host has a thread of its own that spawns it (the kernel SIGKILLs a child when the thread
that forked it exits, see fleet.runtime.processes), talks to it, and splits its output into one
log per hosted node by the logger that printed each line (fleet.runtime.node_log).
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import socket
import sys
import tempfile
import threading
import time
from collections.abc import Mapping
from pathlib import Path
from typing import IO, Any

from fleet.rules import backoff_delay
from fleet.runtime import ament
from fleet.runtime.launch_file import NodeLaunch
from fleet.runtime.node_log import (
    LOG_FORMAT,
    ProcessOutput,
    belongs_to,
    logger_name,
    logger_of,
    prune_rcl_logs,
    rcl_log_dir,
)
from fleet.runtime.processes import group_exists, signal_group, spawn, stop_all
from fleet.runtime.supervisor import BACKOFF, FAILED, RUNNING, STARTING, NodeStatus, ended_problem

HOST_MODULE = "fleet.nodes.host"
CONNECT_TIMEOUT = 60.0  # s: rclpy start-up of a host on a loaded machine
REPLY_TIMEOUT = 60.0  # s: creating a robot's nodes on a loaded machine
POLL = 0.5  # s between status requests (and liveness checks) of a host
STOP_TIMEOUTS = (5.0, 5.0)  # SIGINT, then SIGTERM after the first, SIGKILL after both


# Unix socket paths are limited to 107 bytes: a pool's sockets are in a short private directory
# of the system's temporary one, not in the state dir, which holds a link to it instead, so that
# the next agent on that state dir removes it when a killed agent could not.
SOCKET_DIR_PREFIX = "fleet-hosts-"
SOCKET_DIR_LINK = "sockets"
HOST_STATES = {"running": RUNNING, "backoff": BACKOFF, "failed": FAILED}  # a host's word for a robot -> ours


def node_key(node: NodeLaunch) -> str:
    """A hosted node's name in its robot (and the stem of its log file)."""
    return node.name or node.executable


def node_logger(node: NodeLaunch) -> str:
    """The rcutils logger of a hosted node, by which its lines are filed in its log."""
    return logger_name(node.fqn or node.executable)


def place(occupancy: list[int], group_size: int) -> int | None:
    """Index of the first host with room for one more robot (None: all are full)."""
    return next((index for index, robots in enumerate(occupancy) if robots < group_size), None)


def add_request(robot: str, nodes: list[NodeLaunch]) -> dict[str, Any]:
    """The host request adding `robot`: each node with exactly its own ROS arguments, and the
    logger the host is to say things about it under (a node it cannot make has none of its own)."""
    return {
        "op": "add",
        "robot": robot,
        "respawn": any(node.respawn for node in nodes),
        "respawn_delay": max((node.respawn_delay for node in nodes), default=0.0),
        "nodes": [
            {"executable": node.executable, "ros_args": node.ros_arguments, "logger": node_logger(node)}
            for node in nodes
        ],
    }


def host_command(control: Path) -> list[str]:
    return [sys.executable, "-m", HOST_MODULE, "--control", str(control)]


def host_environment(env: Mapping[str, str], log_dir: Path) -> dict[str, str]:
    result = dict(env)
    result["AMENT_PREFIX_PATH"] = ament.ament_prefix_path(env)
    result.setdefault("PYTHONUNBUFFERED", "1")
    result.setdefault("ROS_LOG_DIR", str(rcl_log_dir(log_dir)))
    result["RCUTILS_CONSOLE_OUTPUT_FORMAT"] = LOG_FORMAT
    result["RCUTILS_COLORIZED_OUTPUT"] = "0"
    return result


class HostedRobot:
    """What the agent knows of one robot in a host: its nodes, their logs, its restarts."""

    def __init__(self, name: str, nodes: list[NodeLaunch], log_dir: Path):
        self.name = name
        self.nodes = nodes
        log_dir.mkdir(parents=True, exist_ok=True)
        self.outputs = {node_key(node): ProcessOutput(log_dir / f"{node_key(node)}.log") for node in nodes}
        self.loggers = {node_logger(node): self.outputs[node_key(node)] for node in nodes}
        self.added = False  # by the current host process
        self.state = STARTING
        self.error = ""
        self.restarts_before = 0  # counted before the current host process (host deaths included)
        self.reported_restarts = 0  # the current host process's count
        # When its nodes were made (time.time()), as the host last said: the uptime it reports
        # is of the moment it was asked, and grows stale until it is asked again.
        self.started_at: float | None = None

    def note(self, text: str) -> None:
        """A line from fleet itself into every node log of this robot."""
        for output in self.outputs.values():
            output.add(f"fleet: {text}")

    def close(self) -> None:
        for output in self.outputs.values():
            output.close()


class HostProcess:
    """One host process, across its restarts, and the robots it holds."""

    def __init__(self, number: int, socket_dir: Path, log_dir: Path, env: Mapping[str, str]):
        self.number = number
        self.name = f"host-{number}"
        self.control = socket_dir / f"{self.name}.sock"
        self.log_dir = log_dir
        self.env = host_environment(env, log_dir)
        self.cmd = host_command(self.control)
        self.output = ProcessOutput(log_dir / f"{self.name}.log")  # lines of no hosted node
        self.robots: dict[str, HostedRobot] = {}
        self.popen: Any = None
        self.failures_in_row = 0
        self.started_at = 0.0
        self._lock = threading.Lock()  # robots, popen
        self._channel_lock = threading.Lock()  # one request/reply at a time
        self._channel: Any = None  # the connection's buffered reader/writer
        self._connection: socket.socket | None = None
        self._wake = threading.Event()
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"fleet-{self.name}", daemon=True)
        self._thread.start()

    # -- other threads --

    def add(self, robot: HostedRobot) -> None:
        """Take `robot`; its nodes are created by this host's thread (status says when)."""
        with self._lock:
            self.robots[robot.name] = robot
        self._wake.set()

    def remove(self, name: str) -> None:
        """Destroy the robot's nodes and forget it (returns when the host has done so)."""
        with self._channel_lock:
            with self._lock:
                robot = self.robots.pop(name, None)
            if robot is None:
                return
            if robot.added and self._channel is not None:
                try:
                    reply = self._call({"op": "remove", "robot": name})
                    if not reply.get("ok"):
                        self.output.add(f"fleet: removing robot {name}: {reply.get('error')}")
                except OSError as error:  # the host is gone: so are the robot's nodes
                    self.output.add(f"fleet: removing robot {name}: {error}")
        robot.close()

    def hosted(self, name: str) -> tuple[HostedRobot | None, Any]:
        """The robot's record and the current process (None: not started)."""
        with self._lock:
            return self.robots.get(name), self.popen

    def size(self) -> int:
        with self._lock:
            return len(self.robots)

    def pid(self) -> int | None:
        with self._lock:
            popen = self.popen
        return popen.pid if popen is not None and popen.poll() is None else None

    def request(self, message: dict[str, Any]) -> dict[str, Any]:
        """One request on the control channel (the fault hook of tests uses it too)."""
        with self._channel_lock:
            if self._channel is None:
                raise OSError(f"{self.name} is not connected")
            return self._call(message)

    def stop(self) -> None:
        self._stopping.set()
        self._wake.set()
        self._thread.join()
        with self._lock:
            robots = list(self.robots.values())
            self.robots.clear()
        for robot in robots:
            robot.close()
        self.output.close()

    # -- this host's thread --

    def _run(self) -> None:
        next_poll = 0.0
        while not self._stopping.is_set():
            try:
                if self.popen is None or self.popen.poll() is not None:
                    self._restart()
                else:
                    self._add_pending()
                    if time.monotonic() >= next_poll:
                        self._poll()
                        next_poll = time.monotonic() + POLL
            except OSError as error:  # the channel broke: the host died or is dying, see above
                self.output.add(f"fleet: {self.name}: {error}")
                self._disconnect()
            except Exception as error:  # never let this thread end: its exit SIGKILLs the host
                self.output.add(f"fleet: {self.name}: {type(error).__name__}: {error}")
            self._wake.wait(POLL)
            self._wake.clear()
        self._terminate()

    def _restart(self) -> None:
        self._disconnect()
        with self._lock:
            robots = list(self.robots.values())
            died = self.popen is not None
        if died:
            code = self.popen.returncode
            signal_group(self.popen.pid, signal.SIGKILL)  # whatever it left in its group
            ran_for = time.monotonic() - self.started_at
            self.failures_in_row = 1 if ran_for >= 10.0 else self.failures_in_row + 1
            delay = backoff_delay(1.0, self.failures_in_row)
            with self._lock:
                self.popen = None
            for robot in robots:
                robot.restarts_before += robot.reported_restarts + 1
                robot.reported_restarts = 0
                robot.added = False
                robot.state = BACKOFF
                robot.error = f"host process {self.name} exited with code {code}"
                robot.note(f"{self.name} exited with code {code}; restarting it in {delay:.1f} s")
            if self._stopping.wait(delay):
                return
        if not robots:
            return  # started when the first robot comes
        self.control.unlink(missing_ok=True)
        prune_rcl_logs(self.log_dir)
        popen = spawn(self.cmd, self.env)
        with self._lock:
            self.popen = popen
        self.started_at = time.monotonic()
        pump = threading.Thread(target=self._split_output, args=(popen.stdout,), daemon=True, name=f"{self.name}-log")
        pump.start()
        self._connect(popen)

    def _connect(self, popen) -> None:
        deadline = time.monotonic() + CONNECT_TIMEOUT
        while True:
            connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
            try:
                connection.connect(str(self.control))
                break
            except OSError:
                connection.close()
                if popen.poll() is not None or self._stopping.is_set():
                    return  # the loop sees it exited
                if time.monotonic() >= deadline:
                    signal_group(popen.pid, signal.SIGKILL)
                    raise OSError(f"no control channel after {CONNECT_TIMEOUT:.0f} s: killed") from None
                time.sleep(0.05)
        connection.settimeout(REPLY_TIMEOUT)
        with self._channel_lock:
            self._connection = connection
            self._channel = connection.makefile("rwb")

    def _disconnect(self) -> None:
        with self._channel_lock:
            if self._channel is not None:
                with contextlib.suppress(OSError):
                    self._channel.close()
            if self._connection is not None:
                self._connection.close()
            self._channel = self._connection = None

    def _call(self, message: dict[str, Any]) -> dict[str, Any]:
        """Send one request and read its reply (the channel lock is held)."""
        assert self._channel is not None
        self._channel.write(json.dumps(message).encode() + b"\n")
        self._channel.flush()
        line = self._channel.readline()
        if not line:
            raise OSError(f"{self.name} closed its control channel")
        return json.loads(line)

    def _add_pending(self) -> None:
        with self._lock:
            pending = [robot for robot in self.robots.values() if not robot.added]
        for robot in pending:
            with self._channel_lock:
                with self._lock:
                    if self.robots.get(robot.name) is not robot:
                        continue  # removed meanwhile
                if self._channel is None:
                    return
                reply = self._call(add_request(robot.name, robot.nodes))
                robot.added = True
                if reply.get("ok"):
                    robot.state, robot.error, robot.started_at = RUNNING, "", time.time()
                else:
                    robot.error = str(reply.get("error", "refused"))
                    # The host says whether it tries again (backoff) or gave up (failed: respawn
                    # is off); a robot shown `failed` while it is tried again ends a deploy's wait.
                    robot.state = HOST_STATES.get(reply.get("state", ""), FAILED)
                    robot.note(f"cannot create the nodes of robot {robot.name}: {robot.error}")

    def _poll(self) -> None:
        with self._channel_lock:
            if self._channel is None:
                return
            reply = self._call({"op": "status"})
        reported = reply.get("robots", {}) if reply.get("ok") else {}
        with self._lock:
            for name, robot in self.robots.items():
                status = reported.get(name)
                if status is None or not robot.added:
                    continue
                robot.reported_restarts = int(status.get("restarts", 0))
                robot.state = HOST_STATES.get(status["state"], STARTING)
                uptime = float(status.get("uptime", 0.0))
                robot.started_at = time.time() - uptime if robot.state == RUNNING else None
                robot.error = str(status.get("error", ""))

    def _split_output(self, stream: IO[bytes]) -> None:
        target = self.output
        with stream:
            for raw in iter(stream.readline, b""):
                line = raw.decode("utf-8", errors="replace").rstrip("\r\n")
                logger = logger_of(line)
                if logger is not None:
                    target = self._output_of(logger)
                target.add(line)

    def _output_of(self, logger: str) -> ProcessOutput:
        """The log of the hosted node owning `logger` (or of a child logger of it)."""
        with self._lock:
            for robot in self.robots.values():
                for name, output in robot.loggers.items():
                    if belongs_to(logger, name):
                        return output
        return self.output

    def _terminate(self) -> None:
        self._disconnect()
        popen = self.popen
        if popen is None:
            return
        began = time.monotonic()
        sent = 0
        while popen.poll() is None or group_exists(popen.pid):
            elapsed = time.monotonic() - began
            stage = 1 + (elapsed >= STOP_TIMEOUTS[0]) + (elapsed >= sum(STOP_TIMEOUTS))
            if stage > sent:
                signal_group(popen.pid, (signal.SIGINT, signal.SIGTERM, signal.SIGKILL)[stage - 1])
                sent = stage
            time.sleep(0.05)
        self.control.unlink(missing_ok=True)


class HostPool:
    """The host processes of one fleet on this agent; robots come and go one at a time."""

    def __init__(self, directory: Path, env: Mapping[str, str], group_size: int):
        if group_size < 1:
            raise ValueError(f"group_size must be at least 1, got {group_size}")
        self.directory = directory
        self.env = dict(env)
        self.group_size = group_size
        self.socket_dir = Path(tempfile.mkdtemp(prefix=SOCKET_DIR_PREFIX))
        directory.mkdir(parents=True, exist_ok=True)
        (directory / SOCKET_DIR_LINK).unlink(missing_ok=True)
        (directory / SOCKET_DIR_LINK).symlink_to(self.socket_dir)
        self.hosts: list[HostProcess] = []
        self._where: dict[str, HostProcess] = {}
        self._numbers = 0
        self._lock = threading.Lock()

    def add_robot(self, robot: str, nodes: list[NodeLaunch], log_dir: Path) -> None:
        hosted = HostedRobot(robot, nodes, log_dir)
        with self._lock:
            if robot in self._where:
                raise ValueError(f"robot {robot!r} is hosted already")
            index = place([host.size() for host in self.hosts], self.group_size)
            if index is None:
                self._numbers += 1
                self.hosts.append(HostProcess(self._numbers, self.socket_dir, self.directory, self.env))
                index = len(self.hosts) - 1
            host = self.hosts[index]
            self._where[robot] = host
        host.add(hosted)

    def remove_robot(self, robot: str) -> None:
        with self._lock:
            host = self._where.pop(robot, None)
        if host is None:
            return
        host.remove(robot)
        with self._lock:
            empty = host.size() == 0 and host in self.hosts and host not in self._where.values()
            if empty:
                self.hosts.remove(host)
        if empty:  # an idle host costs a process: gone with its last robot
            host.stop()

    def robots(self) -> list[str]:
        with self._lock:
            return sorted(self._where)

    def host_of(self, robot: str) -> HostProcess | None:
        with self._lock:
            return self._where.get(robot)

    def node_status(self, robot: str) -> list[NodeStatus]:
        host = self.host_of(robot)
        if host is None:
            return []
        hosted, popen = host.hosted(robot)
        if hosted is None:
            return []
        alive = popen is not None and popen.poll() is None
        state = hosted.state if alive or hosted.state == FAILED else BACKOFF if hosted.added else STARTING
        restarts = hosted.restarts_before + hosted.reported_restarts
        # The host destroys and creates a robot's nodes together, and says why once for them all.
        problem = ended_problem("its hosted nodes", None, restarts, hosted.error) if state in (BACKOFF, FAILED) else ""
        return [
            NodeStatus(
                name=node.name,
                fqn=node.fqn,
                pid=popen.pid if alive and state == RUNNING else None,
                state=state,
                restarts=restarts,
                exit_code=None,
                uptime=round(time.time() - hosted.started_at, 3) if state == RUNNING and hosted.started_at else 0.0,
                cmd=list(host.cmd),
                process=host.name,
                problem=problem,
                ros=True,  # hosted nodes are ROS nodes of the host's process
            )
            for node in hosted.nodes
        ]

    def log_file(self, robot: str, node: str) -> Path | None:
        host = self.host_of(robot)
        if host is None:
            return None
        hosted, _ = host.hosted(robot)
        if hosted is None:
            return None
        for launch in hosted.nodes:
            if node in (launch.name, launch.fqn):
                return hosted.outputs[node_key(launch)].path
        return None

    def stop(self) -> None:
        with self._lock:
            hosts, self.hosts = self.hosts, []
            self._where.clear()
        stop_all(host.stop for host in hosts)
        shutil.rmtree(self.socket_dir, ignore_errors=True)
        (self.directory / SOCKET_DIR_LINK).unlink(missing_ok=True)


def remove_orphaned_socket_dirs(hosts_root: Path) -> None:
    """Remove the socket directories of the host pools under `hosts_root` whose agent was killed
    (their stop never ran): each pool's directory links to its own."""
    for link in hosts_root.glob(f"*/{SOCKET_DIR_LINK}"):
        if link.is_symlink():
            target = Path(os.readlink(link))
            if target.parent == Path(tempfile.gettempdir()) and target.name.startswith(SOCKET_DIR_PREFIX):
                shutil.rmtree(target, ignore_errors=True)  # only ever a directory of ours
        link.unlink(missing_ok=True)
