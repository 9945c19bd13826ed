"""A private control plane for one test fleet: a `fleet router` and `fleet agent` processes.

Each is a real `python -m fleet ...` process, so a test can kill and restart any of them the
way a robot computer crashes and reboots.  They listen and connect on a free loopback port and
keep their state under one directory; every process (and every node the agents start, which
inherit the environment) carries an environment marker, so whatever is left at the end can be
found and stopped.

Router and agents die with the test process, even when it is SIGKILLed (a CI runner, an IDE's
stop button, the OOM killer): they are forked with PR_SET_PDEATHSIG, and an agent's nodes and
helpers die with it in turn.  Otherwise they would outlive it holding the fleet's ROS domain,
whose lock the dead process released.  The kernel sends that signal when the *thread* that
forked them ends, so start and restart a fleet from a thread that outlives it: the main thread,
where pytest runs tests and fixtures.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from fleet import rules
from fleet.lifetime import die_with_parent
from fleet.runtime.processes import STACKS_SIGNAL, STACKS_WAIT
from fleet.testing.isolation import free_tcp_port
from fleet.testing.poll import WaitTimeout, poll

if TYPE_CHECKING:
    from fleet.client import ControlClient

ROUTER = "router"
AGENT_PREFIX = "agent-"


class ControlPlane:
    def __init__(self, root: Path, env: dict[str, str]):
        self.root = root
        self.env = env
        self.port = free_tcp_port()
        self.scheme = "tcp"  # "tls" for a router whose Zenoh config listens with TLS
        self.processes: dict[str, subprocess.Popen] = {}  # "router" or "agent-<name>" -> process
        self.forced: list[str] = []  # what stop_process had to SIGKILL, in words (a leak's likely cause)

    @property
    def endpoint(self) -> str:
        return f"{self.scheme}/127.0.0.1:{self.port}"

    # -- processes ------------------------------------------------------------------------------

    def _spawn(self, key: str, args: list[str]) -> subprocess.Popen:
        if self.pid(key) is not None:
            raise RuntimeError(f"{key} is already running (pid {self.pid(key)})")
        self.root.mkdir(parents=True, exist_ok=True)
        with open(self.log_path(key), "ab") as log:
            process = subprocess.Popen(
                [sys.executable, "-m", "fleet", *args],
                env=self.env,
                cwd=self.root,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
                preexec_fn=die_with_parent,  # see the module's docstring
            )
        self.processes[key] = process
        return process

    def start_router(self, timeout: float = 20.0, zenoh_config: Path | None = None) -> None:
        """Start the router and wait until it answers status queries (with a Zenoh config, which
        may demand credentials this side lacks: until its port is open).  The port was free when
        chosen but another process may take it first: then try a new one (only before agents
        are connected to this one)."""
        ready = self._registry_answers if zenoh_config is None else (lambda: _port_open(self.port))
        for attempt in range(3):
            args = ["router", "--listen", self.endpoint, "--state-dir", str(self.root / ROUTER)]
            process = self._spawn(ROUTER, args + _config_args(zenoh_config))

            def answers_or_exited(process: subprocess.Popen = process) -> bool:
                return bool(ready()) or process.poll() is not None

            try:
                poll(
                    answers_or_exited,
                    timeout=timeout,
                    what="the router to answer",
                )
            except WaitTimeout:
                pass  # stopped below, and tried again on a new port
            else:
                if process.poll() is None:  # it answers (it did not exit)
                    return
            self.stop_process(ROUTER)
            if any(key != ROUTER for key in self.processes) or attempt == 2:
                break
            self.port = free_tcp_port()
        raise RuntimeError(f"the fleet router did not start on {self.endpoint}:\n{self.log_tail(ROUTER)}")

    def start_agent(self, name: str, zenoh_config: Path | None = None) -> None:
        self._spawn(
            agent_key(name),
            [
                "agent",
                "--name",
                name,
                "--connect",
                self.endpoint,
                "--state-dir",
                str(self.agent_dir(name)),
                *_config_args(zenoh_config),
            ],
        )

    def kill(self, key: str, signum: int = signal.SIGKILL) -> int:
        """Signal a router or agent process and wait for it to end; returns its pid."""
        process = self.processes.pop(key)
        process.send_signal(signum)
        try:
            process.wait(timeout=40)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        return process.pid

    def stop_process(self, key: str, timeout: float = 40.0) -> None:
        """SIGTERM (an agent then stops its robots), SIGKILL after `timeout`."""
        process = self.processes.pop(key, None)
        if process is None:
            return
        if process.poll() is None:
            process.terminate()
        try:
            process.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            process.send_signal(STACKS_SIGNAL)  # where it hangs, for the log, before it goes
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(timeout=STACKS_WAIT)
            process.kill()
            process.wait()
            self.forced.append(
                f"{key} (pid {process.pid}) did not exit within {timeout:g} s of SIGTERM: SIGKILLed "
                f"(its threads' stacks then are in {self.log_path(key)})"
            )

    def stop(self) -> None:
        """Agents first (each stops its robots, all at once), then the router."""
        agents = [key for key in self.processes if key != ROUTER]
        for key in agents:
            if self.processes[key].poll() is None:
                self.processes[key].terminate()
        for key in agents:
            self.stop_process(key)
        self.stop_process(ROUTER)

    def pid(self, key: str) -> int | None:
        process = self.processes.get(key)
        return process.pid if process is not None and process.poll() is None else None

    def running(self) -> dict[str, int]:
        """Router and agent processes alive now: key -> pid."""
        return {key: process.pid for key, process in self.processes.items() if process.poll() is None}

    def running_agents(self) -> set[str]:
        return {key[len(AGENT_PREFIX) :] for key in self.running() if key.startswith(AGENT_PREFIX)}

    # -- files ----------------------------------------------------------------------------------

    def agent_dir(self, name: str) -> Path:
        return rules.agent_dir(self.root, name)

    def log_path(self, key: str) -> Path:
        return self.root / f"{key}.log"

    def log_tail(self, key: str, lines: int = 40) -> str:
        path = self.log_path(key)
        if not path.exists():
            return ""
        return "\n".join(path.read_text(errors="replace").splitlines()[-lines:])

    # -- talking to it --------------------------------------------------------------------------

    def client(self) -> ControlClient:
        from fleet.client import ControlClient

        return ControlClient([self.endpoint])

    def _registry_answers(self) -> bool:
        """The router's port is open and its registry (declared just after) answers."""
        if not _port_open(self.port):
            return False
        from fleet.errors import ControlError

        try:
            with self.client() as client:
                return bool(client.status("probe", timeout=1.0)[1])
        except ControlError:
            return False


def _config_args(zenoh_config: Path | None) -> list[str]:
    return [] if zenoh_config is None else ["--zenoh-config", str(zenoh_config)]


def agent_key(name: str) -> str:
    return f"{AGENT_PREFIX}{name}"


def _port_open(port: int) -> bool:
    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) == 0


def child_environment(marker_variable: str, marker: str, state_dir: Path) -> dict[str, str]:
    """This process's environment, cut loose from any fleet the user runs on this machine."""
    env = dict(os.environ)
    for key in ("FLEET_CONNECT", "FLEET_ZENOH_CONFIG", "ROS_LOCALHOST_ONLY"):
        env.pop(key, None)
    env[marker_variable] = marker
    env[rules.STATE_VARIABLE] = str(state_dir)  # never the user's ~/.local/state/fleet
    env["ROS_HOME"] = str(state_dir / "ros")  # rcl log files stay with the test, not in ~/.ros
    env.pop("ROS_LOG_DIR", None)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "UDPv4")
    env["PYTHONUNBUFFERED"] = "1"
    return env
