"""Starting, finding and stopping processes: each node in its own session and dead when its
supervisor dies; the processes that carry a marker in their environment.

Each node runs in its own session (so its own process group): signals go to the whole group,
children of a node included.  Each dies with the thread that forked it (fleet.lifetime), which
covers a SIGKILLed supervisor; so callers must spawn from a thread that lives as long as the
children do.
"""

from __future__ import annotations

import contextlib
import faulthandler
import logging
import os
import signal
import subprocess
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from pathlib import Path
from typing import IO

import psutil

from fleet.lifetime import die_with_parent

_log = logging.getLogger("fleet.processes")
STACKS_SIGNAL = signal.SIGUSR1  # a daemon writes its threads' stacks to stderr (stop_on_signals)
STACKS_WAIT = 1.0  # s to let it write them before it is killed


def spawn(
    cmd: Sequence[str], env: Mapping[str, str], cwd: str | None = None, output: IO | None = None
) -> subprocess.Popen:
    """Start `cmd` in a new session, stdout and stderr merged into one pipe (or into `output`,
    an open file), stdin closed."""
    return subprocess.Popen(
        list(cmd),
        env=dict(env),
        cwd=cwd,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE if output is None else output,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        preexec_fn=die_with_parent,
        close_fds=True,
    )


def signal_group(pgid: int, signum: int) -> bool:
    """Send `signum` to a process group; False when the group no longer exists."""
    try:
        os.killpg(pgid, signum)
        return True
    except ProcessLookupError:
        return False
    except PermissionError:
        # Only possible if the id was reused by someone else's group: it is not ours any more.
        return False


def group_members(pgid: int) -> list[int]:
    """Pids of the live (non-zombie) processes of a process group."""
    members = []
    for pid in psutil.pids():
        try:
            # getpgid first: one system call, where a status reads a file of every process.
            if os.getpgid(pid) == pgid and psutil.Process(pid).status() != psutil.STATUS_ZOMBIE:
                members.append(pid)
        except (ProcessLookupError, psutil.NoSuchProcess):  # it exited since it was listed
            continue
    return members


def group_exists(pgid: int) -> bool:
    """True while a process group has a live member.  Zombies do not count: an orphaned
    member's zombie waits for init to reap it, which some inits do only every second or so."""
    if not signal_group(pgid, 0):
        return False
    return bool(group_members(pgid))


class ServiceProcess:
    """One long-running helper process (a fleet's discovery server, its Zenoh bridge), started
    again when it has died; its output appended to `log_file`.

    Call keep_running() from a thread that lives as long as the process should (see spawn)."""

    def __init__(
        self,
        command: list[str],
        env: Mapping[str, str],
        log_file: Path,
        restart_after: float = 0.0,
        down_since: float | None = None,
    ):
        """restart_after: seconds the service stays down after a process of it died before
        another is started; down_since: the monotonic time from which a predecessor (of an
        earlier run of the caller) may have been down, to count from before the first start."""
        self.command = command
        self.env = dict(env)
        self.log_file = log_file
        self.restart_after = restart_after
        self.down_since = down_since
        self.process: subprocess.Popen | None = None

    @property
    def pid(self) -> int | None:
        process = self.process
        return process.pid if process is not None and process.poll() is None else None

    def keep_running(self) -> None:
        """Start the process if it is not running (first call, or it exited)."""
        if self.process is not None and self.process.poll() is None:
            return
        now = time.monotonic()
        if self.process is not None:
            _log.warning(
                "%s exited with %s: starting it again%s",
                self.command[0],
                self.process.returncode,
                f" in {self.restart_after:g} s" if self.restart_after else "",
            )
            self.process, self.down_since = None, now
        if self.down_since is not None and now - self.down_since < self.restart_after:
            return
        self.down_since = None
        self.log_file.parent.mkdir(parents=True, exist_ok=True)
        with open(self.log_file, "ab") as output:
            self.process = spawn(self.command, self.env, output=output)
        _log.info("started %s (pid %d)", " ".join(self.command[:4]), self.process.pid)

    def stop(self, timeout: float = 5.0) -> None:
        """SIGTERM to its process group, SIGKILL after `timeout`."""
        process, self.process = self.process, None
        if process is None or process.poll() is not None:
            return
        signal_group(process.pid, signal.SIGTERM)
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            signal_group(process.pid, signal.SIGKILL)
            process.wait()


def processes_marked(value: str, variable: str) -> list[psutil.Process]:
    """Live processes (other than this one) whose environment has variable=value: what a
    supervisor started, found again even after they left its process tree."""
    found = []
    me = os.getpid()
    for process in psutil.process_iter(["pid"]):
        if process.pid == me:
            continue
        try:
            if process.environ().get(variable) == value and process.status() != psutil.STATUS_ZOMBIE:
                found.append(process)
        except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
            continue
    return found


def terminate(processes: list[psutil.Process], timeout: float = 5.0) -> None:
    """SIGTERM, wait, then SIGKILL whatever is left."""
    for process in processes:
        with contextlib.suppress(psutil.NoSuchProcess):
            process.terminate()
    _, alive = psutil.wait_procs(processes, timeout=timeout)
    for process in alive:
        with contextlib.suppress(psutil.NoSuchProcess):
            process.kill()
    psutil.wait_procs(alive, timeout=timeout)


def stop_all(stoppers: Iterable[Callable[[], None]]) -> None:
    """Call every `stop` at once, each on its own thread, and return when all have returned: the
    stops of many units or hosts each wait for their processes, so together they take the
    longest one's time, not the sum."""
    threads = [threading.Thread(target=stop) for stop in stoppers]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()


def stop_on_signals(stop: threading.Event | None = None) -> threading.Event:
    """`stop` (or a new event) set by SIGINT or SIGTERM: a daemon finishes cleanly (stops its
    robots, closes its sessions) instead of dying mid-way.  Call from the main thread.

    SIGUSR1 makes it write every thread's stack to stderr (its log), so that a stop that hangs
    can be read before the daemon is killed (fleet.testing does so)."""
    stop = stop or threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    with contextlib.suppress(OSError, ValueError):  # a stderr with no file (captured in-process)
        faulthandler.register(STACKS_SIGNAL, all_threads=True)
    return stop
