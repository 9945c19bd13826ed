"""Run a launch file: start its processes, capture their output, respawn them, stop them cleanly.

One thread per session (the "session thread") does every fork, every reap and every signal.
It lives until all its children are gone, which matters: the children ask the kernel to SIGKILL
them when the thread that forked them exits (PR_SET_PDEATHSIG), so a SIGKILLed supervisor
leaves no orphans, while a short-lived spawning thread would kill them at once.

The session thread sleeps until something happens: a process exits (its pidfd turns readable),
a respawn or a timer falls due, or stop() writes to the wake pipe.  An agent holds a session per
robot, so an idle session must cost nothing: polling at 20 Hz, 1,000 of them took a core.
"""

from __future__ import annotations

import contextlib
import datetime
import os
import select
import shlex
import shutil
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from fleet.errors import FleetError, LaunchFileError, Location, NeedsRos2Launch
from fleet.rules import STABLE_AFTER, backoff_delay
from fleet.runtime import ament
from fleet.runtime.isolation import HOSTED, ISOLATIONS, ProcessSpec, composable, plan_processes
from fleet.runtime.launch_file import LaunchPlan, NodeLaunch, check_launch_file, load_launch_file
from fleet.runtime.node_log import (
    TAIL_LINES,
    ProcessOutput,
    is_launch_logger,
    launch_line,
    logger_of,
    prune_rcl_logs,
    rcl_log_dir,
    routine,
)
from fleet.runtime.processes import group_exists, signal_group, spawn

BACKENDS = ("auto", "embedded", "ros2")
POLL_INTERVAL = 0.05  # while stopping: a process group has no fd to wait on, so it is polled
SESSION = ""  # on_line's process name for the session's own lines (they name what they are about)

# Process states, as status() reports them.
STARTING = "starting"  # not spawned yet
RUNNING = "running"
BACKOFF = "backoff"  # exited, respawn pending
EXITED = "exited"  # exited with 0, no respawn
FAILED = "failed"  # exited non-zero (or by a signal), no respawn
STOPPING = "stopping"
STOPPED = "stopped"  # stopped by stop()


@dataclass(frozen=True)
class NodeStatus:
    name: str | None  # node name (None: the executable's default name)
    fqn: str | None
    pid: int | None  # shared by every node of a composite process
    state: str
    restarts: int
    exit_code: int | None  # negative: killed by that signal
    uptime: float  # seconds since the current process started; 0 when not running
    cmd: list[str]
    process: str  # `controller-1`, `composite-1`, `ros2-launch-1`: log name and screen prefix
    # While its process does not run after having run: how it ended, in words (see ended_problem).
    problem: str = ""
    ros: bool = False  # a ROS node (a `node` of the launch file, with a package), not a plain executable


def default_log_dir() -> Path:
    """`$ROS_LOG_DIR` or `$ROS_HOME/log` or `~/.ros/log`, then a directory for this run."""
    if os.environ.get("ROS_LOG_DIR"):
        base = Path(os.environ["ROS_LOG_DIR"])
    elif os.environ.get("ROS_HOME"):
        base = Path(os.environ["ROS_HOME"]) / "log"
    else:
        base = Path.home() / ".ros" / "log"
    stamp = datetime.datetime.now().strftime("%Y-%m-%d-%H-%M-%S-%f")
    return base / f"fleet-run-{stamp}-{os.getpid()}"


LAST_WORDS = 300  # characters of a process's last line that a problem quotes
WHY_LINES = 5  # the last lines of an ended process looked through for one that may say why


def ended_problem(who: str, exit_code: int | None, restarts: int, last_line: str = "") -> str:
    """Why `who` does not run, in words: how its process ended, how often it was restarted, and
    the last line it printed, which is where a node says why it gives up (a refused parameter):
    `controller exited with code 2 (restarted 4 times): controller: error: ...`."""
    if exit_code is None:
        text = f"{who} stopped"
    elif exit_code < 0:
        try:
            text = f"{who} was killed by {signal.Signals(-exit_code).name}"
        except ValueError:
            text = f"{who} was killed by signal {-exit_code}"
    else:
        text = f"{who} exited with code {exit_code}"
    if restarts:
        text += f" (restarted {restarts} time{'s' if restarts != 1 else ''})"
    last_line = " ".join(last_line.split())
    if last_line:
        text += f": {last_line[:LAST_WORDS]}"
    return text


class _Supervised:
    """One process slot of the session, across its respawns."""

    def __init__(self, spec: ProcessSpec, output: ProcessOutput):
        self.spec = spec
        self.output = output
        self.popen: subprocess.Popen | None = None
        self.pidfd: int | None = None  # readable once the process has exited
        self.pump: threading.Thread | None = None  # reads its output
        self.state = STARTING
        self.restarts = 0
        self.exit_code: int | None = None
        self.started_at = 0.0
        self.restart_at: float | None = None
        self.failures_in_row = 0
        self.end_logged = True  # whether its log says how its last process ended (none ran yet)

    @property
    def pid(self) -> int | None:
        return self.popen.pid if self.popen is not None else None

    def printed(self, count: int) -> list[str]:
        """The last `count` lines its processes printed: its log without the session's own lines
        on when each started and how it ended.  Read from the end, as far as needed: status asks
        for the last line of every ended process each time it reports."""
        found: list[str] = []
        for line in reversed(self.output.tail(TAIL_LINES) if count > 0 else []):
            if not is_launch_logger(logger_of(line) or ""):
                found.append(line)
                if len(found) == count:
                    break
        return found[::-1]

    def finished(self) -> bool:
        """True when its process and every other member of its group are gone."""
        if self.popen is None:
            return True
        if self.popen.poll() is None:
            return False
        return not group_exists(self.popen.pid)


class LaunchSession:
    """The processes of one launch file.  See docs/architecture.md, "Runtime"."""

    def __init__(
        self,
        path: str | Path,
        launch_args: Mapping[str, str] | None = None,
        env: Mapping[str, str] | None = None,
        log_dir: str | Path | None = None,
        isolation: str = "process",
        backend: str = "auto",
        stop_timeouts: tuple[float, float] = (5.0, 10.0),
        on_line: Callable[[str, str], None] | None = None,
    ):
        if isolation not in ISOLATIONS:
            raise FleetError(f"isolation must be one of {', '.join(ISOLATIONS)}, got '{isolation}'")
        if backend not in BACKENDS:
            raise FleetError(f"backend must be one of {', '.join(BACKENDS)}, got '{backend}'")
        self.path = Path(path).absolute()
        self.launch_args = dict(launch_args or {})
        self.base_env = dict(os.environ if env is None else env)
        self.log_dir = Path(log_dir) if log_dir is not None else default_log_dir()
        self.isolation = isolation
        self.requested_backend = backend
        self.backend: str | None = None  # the backend start() chose
        self.sigterm_after, self.sigkill_after = stop_timeouts
        # on_line(process_name, line): what processes with output: screen print, and (process
        # name SESSION) the session's own lines: `log` actions, every process's start and end.
        self.on_line = on_line
        self.plan: LaunchPlan | None = None
        self._processes: list[_Supervised] = []
        self._lock = threading.Lock()
        self._changed = threading.Condition(self._lock)  # notified after the session thread looked
        self._wake_read, self._wake_write = -1, -1  # the pipe that wakes the session thread
        self._started = threading.Event()
        self._start_error: BaseException | None = None
        self._stop_requested = False
        self._thread: threading.Thread | None = None

    # -- public API --

    def start(self) -> None:
        """Check the launch file, then start every process.  Raises FleetError (nothing started)
        when the file cannot be run."""
        if self._thread is not None:
            raise RuntimeError("session already started")
        specs = self._prepare()
        if self.on_line is not None and self.plan is not None:
            for message in self.plan.logs:  # `log` actions say their piece before anything starts
                self.on_line(SESSION, f"[INFO] [launch.user]: {message}")
        self.log_dir.mkdir(parents=True, exist_ok=True)
        for spec in specs:
            echo = None
            if spec.echo and self.on_line is not None:
                echo = self._echo_for(spec.name)
            output = ProcessOutput(self.log_dir / f"{spec.name}.log", echo)
            self._processes.append(_Supervised(spec, output))
        self._wake_read, self._wake_write = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
        self._thread = threading.Thread(target=self._run, name="fleet-session", daemon=True)
        self._thread.start()
        self._started.wait()
        if self._start_error is not None:
            self._thread.join()
            self._close_wake_pipe()
            raise self._start_error

    def check(self) -> None:
        """Raise what start() would raise about the launch file (FleetError); start and write
        nothing."""
        self._prepare(check_only=True)

    def status(self) -> list[NodeStatus]:
        now = time.monotonic()
        result = []
        with self._lock:
            for process in self._processes:
                uptime = now - process.started_at if process.state == RUNNING else 0.0
                problem = self._problem(process)
                nodes: list[NodeLaunch | None] = list(process.spec.nodes) or [None]
                for node in nodes:
                    result.append(
                        NodeStatus(
                            name=node.name if node is not None else self.path.name,
                            fqn=node.fqn if node is not None else None,
                            pid=process.pid if process.state in (RUNNING, STOPPING) else None,
                            state=process.state,
                            restarts=process.restarts,
                            exit_code=process.exit_code,
                            uptime=round(uptime, 3),
                            cmd=list(process.spec.cmd),
                            process=process.spec.name,
                            problem=problem,
                            ros=node is not None and bool(node.package),
                        )
                    )
        return result

    @staticmethod
    def _problem(process: _Supervised) -> str:
        """How the process ended, while it has ended and not been started again ("" otherwise)."""
        if process.state not in (BACKOFF, EXITED, FAILED):
            return ""
        nodes = process.spec.nodes
        who = nodes[0].name if len(nodes) == 1 and nodes[0].name else process.spec.name
        # Its last words, if they may say why (a SIGKILLed node's last INFO line does not).
        last = [line for line in process.printed(WHY_LINES) if not routine(line)][-1:]
        return ended_problem(who, process.exit_code, process.restarts, last[0] if last else "")

    def hosted_nodes(self) -> list[NodeLaunch]:
        """The nodes this session leaves to an agent's host processes (isolation: agent)."""
        if self.isolation != HOSTED or self.plan is None:
            return []
        return [node for node in self.plan.nodes if composable(node)]

    def tail(self, node: str, lines: int = 20) -> list[str]:
        """Last lines the process hosting `node` (a node name, fqn, or process name) printed."""
        return self._find(node).printed(lines)

    def log_file(self, node: str) -> Path:
        return self._find(node).output.path

    def done(self) -> bool:
        """True when nothing runs and nothing will be respawned."""
        with self._lock:
            return self._done_locked()

    def wait(self, timeout: float | None = None) -> bool:
        """Wait until done(); False on timeout."""
        with self._changed:
            return self._changed.wait_for(self._done_locked, timeout)

    def failed(self) -> list[NodeStatus]:
        return [status for status in self.status() if status.state == FAILED]

    def stop(self) -> None:
        """SIGINT to every process group, SIGTERM after the first timeout, SIGKILL after the
        second; returns when every process (and its group) is gone."""
        if self._thread is None:
            return
        self._stop_requested = True
        self._wake_up()
        self._thread.join()
        for process in self._processes:
            if process.pump is not None:
                process.pump.join(timeout=1.0)  # the last lines a node printed
            self._log_end(process)
            process.output.close()
        self._close_wake_pipe()
        # Nothing of this session reads its inline parameter files any more (a respawn would):
        # left behind, every restart or redeploy of a unit added its own set to its log directory.
        for name in self.plan.params_files if self.plan is not None else []:
            Path(name).unlink(missing_ok=True)

    def __enter__(self) -> LaunchSession:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _done_locked(self) -> bool:
        return all(p.state in (EXITED, FAILED, STOPPED) for p in self._processes)

    def _close_wake_pipe(self) -> None:
        if self._wake_write >= 0:  # a second stop() finds it closed
            os.close(self._wake_read)
            os.close(self._wake_write)
            self._wake_read, self._wake_write = -1, -1

    def _wake_up(self) -> None:
        if self._wake_write < 0:  # stopped already
            return
        with contextlib.suppress(BlockingIOError):  # full: the thread is due to wake anyway
            os.write(self._wake_write, b"w")

    # -- preparation (caller's thread) --

    def _ros2(self) -> str | None:
        return shutil.which("ros2", path=self.base_env.get("PATH", os.defpath))

    def _child_env(self, extra: Mapping[str, str], unset: tuple[str, ...] = ()) -> dict[str, str]:
        env = {name: value for name, value in self.base_env.items() if name not in unset}
        env["AMENT_PREFIX_PATH"] = ament.ament_prefix_path(self.base_env)
        env.setdefault("PYTHONUNBUFFERED", "1")  # node output reaches the log line by line
        env.setdefault("ROS_LOG_DIR", str(rcl_log_dir(self.log_dir)))
        env.update(extra)
        return env

    def _prepare(self, check_only: bool = False) -> list[ProcessSpec]:
        with contextlib.suppress(OSError):  # a read-only environment: fleet_nodes lookups will say what is missing
            ament.ensure_ament_prefix()
        ros2 = self._ros2()
        backend = self.requested_backend
        if backend == "auto":
            # Robot isolation is ours: only the embedded runner can share processes.
            backend = "ros2" if ros2 is not None and self.isolation == "process" else "embedded"
        if backend == "ros2":
            if ros2 is None:
                raise FleetError("backend 'ros2' needs the `ros2` command on PATH")
            if self.isolation != "process":
                raise FleetError(f"isolation '{self.isolation}' needs the embedded backend")
            if not self.path.is_file():
                raise LaunchFileError("launch file not found", Location(self.path))
            if check_only:  # what ros2 launch would refuse too (a missing executable); not what only it reads
                with contextlib.suppress(NeedsRos2Launch):
                    self._check_file()
                return []
            self.backend = "ros2"
            return [self._ros2_spec(ros2)]
        self.backend = "embedded"
        try:
            if check_only:  # the same reading, without writing the inline parameter files
                self._check_file()
                return []
            self.plan = load_launch_file(
                self.path,
                self.launch_args,
                env=self.base_env,
                params_dir=self.log_dir / "params",
                ament_search_path=ament.ament_prefix_path(self.base_env),
            )
        except NeedsRos2Launch as problem:  # only then would ros2 launch have helped
            if self.requested_backend == "auto" and ros2 is None:
                problem.message += " (and `ros2` is not on PATH to run it with ros2 launch)"
            raise
        return plan_processes(self.plan.nodes, self.isolation)

    def _check_file(self) -> None:
        check_launch_file(self.path, self.launch_args, self.base_env, ament.ament_prefix_path(self.base_env))

    def _ros2_spec(self, ros2: str) -> ProcessSpec:
        arguments = [f"{name}:={value}" for name, value in self.launch_args.items()]
        return ProcessSpec(name="ros2-launch-1", cmd=[ros2, "launch", str(self.path), *arguments], echo=True)

    def _echo_for(self, process_name: str) -> Callable[[str], None]:
        on_line = self.on_line
        assert on_line is not None
        return lambda line: on_line(process_name, line)

    def _find(self, node: str) -> _Supervised:
        for process in self._processes:
            names = {process.spec.name}
            for launch in process.spec.nodes:
                names.update(name for name in (launch.name, launch.fqn) if name)
            if node in names:
                return process
        raise KeyError(f"no node or process named {node!r} in {self.path.name}")

    # -- the session thread --

    def _run(self) -> None:
        try:
            began = time.monotonic()
            for process in self._processes:
                if process.spec.delay > 0.0:  # a timer's: started by _check when due
                    process.restart_at = began + process.spec.delay
                else:
                    self._spawn(process)
        except BaseException as problem:  # e.g. a missing interpreter: stop what started
            self._start_error = FleetError(f"cannot start {process.spec.name}: {problem}")
            self._stop_requested = True
        finally:
            self._started.set()
        stop_began: float | None = None
        signals_sent = 0
        while True:
            now = time.monotonic()
            with self._lock:
                due = [process for process in self._processes if self._check(process, now)]
            for process in due:
                self._respawn(process)
            timeout = self._next_event(now)
            if self._stop_requested:
                if stop_began is None:
                    stop_began = now
                if all(process.finished() for process in self._processes):
                    break
                # SIGINT at once, SIGTERM after sigterm_after, SIGKILL sigkill_after later.
                stage = 1
                if now - stop_began >= self.sigterm_after:
                    stage = 2
                if now - stop_began >= self.sigterm_after + self.sigkill_after:
                    stage = 3
                if stage > signals_sent:
                    signum = {1: signal.SIGINT, 2: signal.SIGTERM, 3: signal.SIGKILL}[stage]
                    for process in self._processes:
                        if process.popen is not None and not process.finished():
                            signal_group(process.popen.pid, signum)
                    signals_sent = stage
                timeout = POLL_INTERVAL
            with self._changed:
                self._changed.notify_all()
            self._sleep(timeout)
        with self._changed:
            for process in self._processes:
                self._check(process, time.monotonic())
                if process.state in (RUNNING, STOPPING, BACKOFF, STARTING):
                    process.state = STOPPED
                self._close_pidfd(process)
            self._changed.notify_all()

    def _next_event(self, now: float) -> float | None:
        """Seconds until the next respawn or timer is due (None: nothing is due, sleep until a
        process exits or stop() wakes us)."""
        with self._lock:
            due_at = [
                p.restart_at for p in self._processes if p.state in (STARTING, BACKOFF) and p.restart_at is not None
            ]
            unwatched = any(p.state == RUNNING and p.pidfd is None for p in self._processes)
        timeout = max(0.0, min(due_at) - now) if due_at else None
        if unwatched:  # no pidfd (a kernel before 5.3): notice its exit by polling
            timeout = POLL_INTERVAL if timeout is None else min(timeout, POLL_INTERVAL)
        return timeout

    def _sleep(self, timeout: float | None) -> None:
        """Until a watched process exits, the wake pipe is written, or `timeout` seconds pass."""
        poller = select.poll()
        poller.register(self._wake_read, select.POLLIN)
        for process in self._processes:
            if process.pidfd is not None:
                poller.register(process.pidfd, select.POLLIN)
        poller.poll(None if timeout is None else timeout * 1000.0)
        with contextlib.suppress(BlockingIOError):
            os.read(self._wake_read, 4096)

    @staticmethod
    def _close_pidfd(process: _Supervised) -> None:
        if process.pidfd is not None:
            os.close(process.pidfd)
            process.pidfd = None

    def _respawn(self, process: _Supervised) -> None:
        # An exception must not end this thread: its exit would SIGKILL every other node.
        try:
            self._spawn(process)
        except OSError as problem:
            process.output.add(f"fleet: cannot respawn {process.spec.name}: {problem}")
            with self._lock:
                process.state = FAILED

    def _spawn(self, process: _Supervised) -> None:
        spec = process.spec
        env = self._child_env(spec.env, spec.env_unset)
        prune_rcl_logs(self.log_dir)
        popen = spawn(spec.cmd, env, cwd=spec.cwd)
        try:
            pidfd: int | None = os.pidfd_open(popen.pid)  # only this thread reaps: it cannot be reaped yet
        except OSError:  # no pidfd on this kernel: _next_event polls instead
            pidfd = None
        with self._lock:
            process.popen = popen
            process.pidfd = pidfd
            process.state = RUNNING  # exit_code stays: the last exit, why it was started again
            process.started_at = time.monotonic()
            process.restart_at = None
            process.end_logged = False
        self._say(process, "INFO", f"process started with pid [{popen.pid}]")
        assert popen.stdout is not None  # spawn() pipes the output when given no file
        process.pump = process.output.follow(popen.stdout)

    def _log_end(self, process: _Supervised) -> None:
        """Say how the process ended, once, after its last lines (as `ros2 launch` reports a
        process that finished or died): `fleet logs` shows where one process of a node ends and
        the next begins."""
        popen = process.popen
        if process.end_logged or popen is None or popen.returncode is None:
            return
        process.end_logged = True
        if popen.returncode == 0:
            self._say(process, "INFO", f"process has finished cleanly [pid {popen.pid}]")
        else:
            what = f"pid {popen.pid}, exit code {popen.returncode}, cmd: {shlex.join(process.spec.cmd)}"
            self._say(process, "ERROR", f"process has died [{what}]")

    def _say(self, process: _Supervised, severity: str, message: str) -> None:
        """A line of the session's own about a process, into its log; on screen whatever the
        process's `output` (ros2 launch prints these for every process)."""
        line = launch_line(process.spec.name, severity, message)
        process.output.add(line, echo=False)
        if self.on_line is not None:
            # Said on the session thread, which must not end (every node would go with it): a
            # screen gone away (`fleet run ... | head`) loses the line, the log keeps it.
            with contextlib.suppress(OSError):
                self.on_line(SESSION, line)

    def _check(self, process: _Supervised, now: float) -> bool:
        """Notice an exit and decide on a respawn (called with the lock held).  Returns True
        when the process is due to be started again."""
        popen = process.popen
        if process.state in (RUNNING, STOPPING) and popen is not None and popen.poll() is not None:
            self._close_pidfd(process)
            process.exit_code = popen.returncode
            if self._stop_requested:
                process.state = STOPPED
                return False
            # The node is gone; whatever it left in its group goes too.
            signal_group(popen.pid, signal.SIGKILL)
            # Its last lines are read before it is declared ended: they say why (status quotes them).
            if process.pump is not None:
                process.pump.join(timeout=0.5)
            self._log_end(process)
            if not process.spec.respawn:
                process.state = EXITED if process.exit_code == 0 else FAILED
                return False
            ran_for = now - process.started_at
            process.failures_in_row = 1 if ran_for >= STABLE_AFTER else process.failures_in_row + 1
            process.state = BACKOFF
            process.restart_at = now + backoff_delay(process.spec.respawn_delay, process.failures_in_row)
        elif process.state == RUNNING and self._stop_requested:
            process.state = STOPPING
        elif process.state == STARTING and process.restart_at is not None:  # a timer's, not started yet
            if self._stop_requested:
                process.state = STOPPED
            elif now >= process.restart_at:
                return True
        elif process.state == BACKOFF:
            if self._stop_requested:
                process.state = STOPPED
            elif process.restart_at is not None and now >= process.restart_at:
                process.restarts += 1
                return True
        return False
