"""Helpers for the control-plane tests. A real control plane on loopback: a router and agents as separate processes, own ports,
own ROS domain, own state directories; and a tiny node stand-in so most tests run no rclpy."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import yaml

from fleet.testing.isolation import free_tcp_port

DATA = Path(__file__).parent / "data"
REPO = Path(__file__).resolve().parents[2]


def make_prefix(root: Path) -> Path:
    """An ament prefix with package fleet_test and its executable `sleeper`."""
    index = root / "share" / "ament_index" / "resource_index" / "packages"
    index.mkdir(parents=True, exist_ok=True)
    (index / "fleet_test").write_text("")
    (root / "share" / "fleet_test").mkdir(parents=True, exist_ok=True)
    executable = root / "lib" / "fleet_test" / "sleeper"
    executable.parent.mkdir(parents=True, exist_ok=True)
    executable.write_text(f"#!{sys.executable}\n" + (DATA / "sleeper.py").read_text())
    executable.chmod(0o755)
    return root


def wait_until(predicate, timeout: float, interval: float = 0.1):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() >= deadline:
            return value
        time.sleep(interval)


class Cluster:
    """Router + agents as subprocesses; every process is stopped by stop()."""

    def __init__(self, root: Path, domain_id: int, extra_env: dict[str, str] | None = None):
        self.root = root
        self.domain_id = domain_id
        self.port = free_tcp_port()
        self.endpoint = f"tcp/127.0.0.1:{self.port}"
        self.processes: dict[str, subprocess.Popen] = {}
        self.prefix = make_prefix(root / "prefix")
        self.env = dict(os.environ)
        self.env["AMENT_PREFIX_PATH"] = str(self.prefix)
        self.env.pop("FLEET_ZENOH_CONFIG", None)
        self.env.update(extra_env or {})

    def _spawn(self, key: str, args: list[str], env: dict[str, str] | None = None) -> subprocess.Popen:
        log = open(self.root / f"{key}.log", "ab")
        process = subprocess.Popen([sys.executable, "-m", "fleet", *args], env=env or self.env,
                                   stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        log.close()
        self.processes[key] = process
        return process

    def start_router(self, config: Path | None = None) -> subprocess.Popen:
        args = ["router", "--listen", self.endpoint, "--state-dir", str(self.root / "router")]
        if config:
            args += ["--zenoh-config", str(config)]
        process = self._spawn("router", args)
        assert wait_until(lambda: _port_open(self.port) or process.poll() is not None, 10)
        assert process.poll() is None, self.log("router")
        if config is None:  # the registry is declared a little after the port opens: wait for it
            assert wait_until(self._registry_answers, 10), self.log("router")
        return process

    def _registry_answers(self) -> bool:
        from fleet.errors import ControlError

        try:
            with self.client() as client:
                return bool(client.status("probe")[1])
        except ControlError:
            return False

    def start_agent(self, name: str, config: Path | None = None) -> subprocess.Popen:
        args = ["agent", "--name", name, "--connect", self.endpoint, "--state-dir", str(self.state_dir(name))]
        if config:
            args += ["--zenoh-config", str(config)]
        return self._spawn(f"agent-{name}", args)

    def state_dir(self, agent: str) -> Path:
        return self.root / "agents" / agent

    def log(self, key: str) -> str:
        path = self.root / f"{key}.log"
        return path.read_text(errors="replace")[-4000:] if path.exists() else ""

    def kill(self, key: str, signum: int = signal.SIGKILL) -> None:
        process = self.processes.pop(key)
        process.send_signal(signum)
        process.wait(timeout=30)

    def stop(self) -> None:
        agents = [key for key in self.processes if key != "router"]
        for key in agents + ["router"]:
            process = self.processes.get(key)
            if process is not None and process.poll() is None:
                process.terminate()
        for key in agents + ["router"]:
            process = self.processes.pop(key, None)
            if process is None:
                continue
            try:
                process.wait(timeout=20)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()

    # -- specs and clients --

    def spec(self, name: str = "tiny", robots: list[dict] | None = None, **changes) -> Path:
        data = yaml.safe_load((DATA / "tiny.yaml").read_text())
        data["templates"] = str(DATA / "templates")
        data["ros"]["domain_id"] = self.domain_id
        if robots is not None:
            data["robots"] = robots
        data.update(changes)
        path = self.root / f"{name}-{time.monotonic_ns()}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path

    def client(self, config: Path | None = None):
        from fleet.control.client import ControlClient

        return ControlClient([self.endpoint], config)

    def deploy(self, spec: Path, sets: list[str] = (), timeout: float = 30.0, wait: bool = True):
        from fleet.control.deploy import deploy
        from fleet.expand import expand_fleet
        from fleet.spec import load_spec

        expansion = expand_fleet(load_spec(spec), list(sets))
        with self.client() as client:
            return deploy(client, expansion, wait=wait, timeout=timeout)

    def view(self, fleet: str | None = None):
        from fleet.control.view import build_view

        with self.client() as client:
            return build_view(*client.status(fleet), time.time())

    def cli(self, *args: str, timeout: float = 60, env: dict[str, str] | None = None) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "fleet", *args], env=env or self.env, capture_output=True,
                              text=True, timeout=timeout)

    def wait_agents_online(self, *names: str, timeout: float = 15.0) -> None:
        """Agents answer status (an idle one answers too)."""
        def online():
            view = self.view()
            return all(any(a.name == n and a.online for a in view.agents) for n in names)

        assert wait_until(online, timeout), "\n".join(self.log(f"agent-{n}") for n in names)


def _port_open(port: int) -> bool:
    with socket.socket() as sock:
        return sock.connect_ex(("127.0.0.1", port)) == 0


def robot(view, name: str):
    return next(row for row in view.robots if row.name == name)
