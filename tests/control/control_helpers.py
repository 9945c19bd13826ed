"""Helpers for the control-plane tests. A real control plane on loopback: a router and agents as
separate processes, own ports, own ROS domain, own state directories; and a tiny rclpy node as
the stand-in for a robot's nodes."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import psutil
import yaml

from fleet.testing.control_plane import ControlPlane
from fleet.testing.poll import poll
from tests.checkout import FLEETS

if TYPE_CHECKING:
    from fleet.client import ControlClient

DATA = Path(__file__).parent / "data"


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


class Cluster(ControlPlane):
    """fleet.testing's control plane (router + agents as subprocesses, stopped by stop()), with
    an ament prefix holding the tiny stand-in node, and the specs and views the tests use."""

    spec_file: Path  # the spec a module's tests deploy (set by its fixture)

    def __init__(self, root: Path, domain_id: int, extra_env: dict[str, str] | None = None):
        root.mkdir(parents=True, exist_ok=True)
        self.domain_id = domain_id
        self.prefix = make_prefix(root / "prefix")
        env = dict(os.environ)
        env["AMENT_PREFIX_PATH"] = str(self.prefix)
        env.pop("FLEET_ZENOH_CONFIG", None)
        env.update(extra_env or {})
        super().__init__(root, env)

    def start_agent(self, name: str, config: Path | None = None) -> None:
        super().start_agent(name, zenoh_config=config)

    def state_dir(self, agent: str) -> Path:
        return self.agent_dir(agent)

    def log(self, key: str) -> str:
        path = self.log_path(key)
        return path.read_text(errors="replace")[-4000:] if path.exists() else ""

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

    def two_robots_on_host_a(self, isolation: str) -> Path:
        """fleets/two_robots.yaml (real nodes and world) in this cluster's domain, all on agent
        hostA, with that isolation."""
        data = yaml.safe_load((FLEETS / "two_robots.yaml").read_text())
        data["ros"]["domain_id"] = self.domain_id
        data["agents"] = {"hostA": {}}
        data["defaults"]["agent"] = "hostA"
        data["defaults"]["isolation"] = isolation
        path = self.root / f"two_robots-{isolation}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        return path

    def client(self, config: Path | None = None) -> ControlClient:
        from fleet.client import ControlClient

        return ControlClient([self.endpoint], config)

    def deploy(self, spec: Path, sets: Sequence[str] = (), timeout: float = 30.0, wait: bool = True):
        from fleet.client import deploy
        from fleet.expand import expand_fleet
        from fleet.spec import load_spec

        expansion = expand_fleet(load_spec(spec), list(sets))
        with self.client() as client:
            return deploy(client, expansion, wait=wait, timeout=timeout)

    def view(self, fleet: str | None = None, config: Path | None = None):
        from fleet.plan import build_view

        with self.client(config) as client:
            return build_view(*client.status(fleet), time.time())

    def cli(
        self, *args: str, timeout: float = 60, env: dict[str, str] | None = None, cwd: Path | None = None
    ) -> subprocess.CompletedProcess:
        return subprocess.run(
            [sys.executable, "-m", "fleet", *args],
            env=env or self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
            cwd=cwd,
        )

    def wait_agents_online(self, *names: str, timeout: float = 15.0) -> None:
        """Agents answer status (an idle one answers too)."""

        def online():
            view = self.view()
            return all(any(a.name == n and a.online for a in view.agents) for n in names)

        poll(
            online,
            timeout=timeout,
            what=f"agents {', '.join(names)} online",
            explain=lambda: "\n".join(self.log(f"agent-{n}") for n in names),
        )


# The controller's own words for such a route (its rules, fleet/nodes/parameters.py).
ROUTE_REFUSAL = "waypoints must be x,y pairs (even length >= 2), got 3 values"


def with_refused_route(template: Path, directory: Path, robot: str) -> str:
    """Template `template` (with its parameter defaults) copied into `directory` as site_NAME,
    whose controller reads a route file of the agent's computer after the robot's parameter file
    (a route surveyed on site, say), which holds a route of 3 values for `robot`: the controller
    refuses it at every start (ROUTE_REFUSAL).  In the spec or with --set, `fleet render` would
    refuse such a route (the controller's rules); a file it cannot see reaches the controller.
    Returns the copy's name."""
    directory.mkdir(parents=True, exist_ok=True)
    route = directory / "routes.yaml"
    route.write_text(f"/{robot}/controller:\n  ros__parameters:\n    waypoints: [1.0, 2.0, 3.0]\n")
    name = "site_" + template.name.removesuffix(".launch.yaml.j2")
    text = template.read_text()
    robot_file = "      - from: {{ params_file }}\n"
    assert text.index("exec: controller") < text.index(robot_file), "the controller is the template's first node"
    (directory / f"{name}.launch.yaml.j2").write_text(
        text.replace(robot_file, f"{robot_file}      - from: {route}\n", 1)
    )
    defaults = template.with_name(template.name.replace(".launch.yaml.j2", ".params.yaml"))
    (directory / f"{name}.params.yaml").write_text(defaults.read_text())
    return name


def robot(view, name: str):
    return next(row for row in view.robots if row.name == name)


def wait_processes_gone(pids, timeout: float) -> None:
    """Until none of `pids` is a live process."""
    poll(
        lambda: sorted(pid for pid in pids if psutil.pid_exists(pid)),
        until=lambda alive: not alive,
        timeout=timeout,
        what=f"processes {sorted(pids)} to end",
        describe=lambda alive: f"still alive: {alive}",
    )


def thread_names(pid: int) -> list[str]:
    return sorted(Path(task, "comm").read_text().strip() for task in Path(f"/proc/{pid}/task").iterdir())


def zenoh_runtimes(names: list[str]) -> set[str]:
    """Zenoh names its runtimes' threads <runtime>-<index>: app-0, rx-1, tx-0, ..."""
    return {name.rpartition("-")[0] for name in names if name.rpartition("-")[2].isdigit()}
