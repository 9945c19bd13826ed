"""One fleet on three computers: Linux network namespaces on one LAN (fleet.testing.netns).

`sim` runs the router and the agent `sim_host` (the world and the fleet's DDS discovery server);
`rack_a` and `rack_b` each run an agent with two robots.  Everything goes through the `fleet`
command run on `sim`, as a user at the workstation would.  Checked: every robot moves; a robot
on one computer meets a robot from another (its safety node stops it on its lidar, and the other
bumps into it); `fleet param`, `fleet logs` and `fleet restart` reach robots on other computers; a frozen world
makes every robot `degraded` with the reason, and they recover; a pulled cable shows in status
and the robots come back when it is plugged in; nothing is left running.  And the same fleet with
mutual TLS between the computers, set up as docs/multi-computer.md tells a user to.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any

import psutil
import pytest
import yaml

from fleet.runtime.node_log import belongs_to, is_launch_logger, logger_of
from fleet.testing.netns import Lan, netns_problem
from fleet.testing.poll import poll
from fleet.testing.processes import MARKER_VARIABLE, processes_marked

pytestmark = pytest.mark.integration

PORT = 7447  # each computer is its own network namespace: the default port is free on each

SPEC: dict[str, Any] = {
    "fleet": "lan",
    "ros": {"domain_id": 0, "use_sim_time": True},
    "world": {
        "agent": "sim_host",
        "physics_rate": 240,
        "real_time": True,
        "obstacles": [{"name": "wall_south", "type": "wall", "position": [2.0, -4.0], "size": [12.0, 0.2, 0.5]}],
    },
    "agents": {"sim_host": {}, "rack_a": {}, "rack_b": {}},
    "defaults": {
        "template": "diff_drive",
        "agent": "rack_a",
        "isolation": "robot",
        "model": {"type": "light", "radius": 0.2},
        "parameters": {"controller": {"max_speed": 0.4}, "battery": {"capacity": 50.0}},
    },
    "robots": [
        # a1 (rack_a) and b1 (rack_b) drive head-on: a1's safety node stops it on its lidar, b1
        # has no safety node and bumps into it.
        {
            "name": "a1",
            "pose": {"x": 0.0, "y": 0.0, "yaw": 0.0},
            "parameters": {"controller": {"waypoints": [3.0, 0.0], "loop": False}},
        },
        {
            "name": "b1",
            "agent": "rack_b",
            "pose": {"x": 3.0, "y": 0.0, "yaw": 3.1416},
            "launch_args": {"enable_safety": False},
            "parameters": {"controller": {"waypoints": [3.0, 0.0], "loop": False}},
        },
        {
            "name": "a2",
            "pose": {"x": -2.0, "y": 3.0, "yaw": 0.0},
            "parameters": {"controller": {"waypoints": [1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]}},
        },
        {
            "name": "b2",
            "agent": "rack_b",
            "pose": {"x": 5.0, "y": 3.0, "yaw": 0.0},
            "parameters": {"controller": {"waypoints": [1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]}},
        },
    ],
}
ROBOTS = ("a1", "a2", "b1", "b2")
AGENT_HOSTS = {"sim_host": "sim", "rack_a": "rack_a", "rack_b": "rack_b"}
LIST_TOPICS = """
import time, rclpy
rclpy.init()
node = rclpy.create_node("graph_lister")
end = time.monotonic() + 5
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.2)
print(sorted(name for name, _ in node.get_topic_names_and_types()))
"""


@pytest.fixture
def lan():
    problem = netns_problem()
    if problem:
        pytest.skip(problem)
    with Lan(["sim", "rack_a", "rack_b"]) as network:
        yield network


class Fleet:
    """The router and agents of the LAN's computers, and the `fleet` command on `sim`."""

    def __init__(self, lan: Lan, root: Path):
        self.lan, self.root = lan, root
        self.transport = "dds"
        self.endpoint = f"tcp/{lan.hosts['sim'].address}:{PORT}"
        self.processes: dict[str, subprocess.Popen] = {}
        self.env = dict(
            os.environ, FLEET_STATE_DIR=str(root / "state"), ROS_HOME=str(root / "ros"), PYTHONUNBUFFERED="1"
        )
        for key in ("FLEET_CONNECT", "FLEET_ZENOH_CONFIG", "ROS_DISCOVERY_SERVER", "ROS_LOG_DIR"):
            self.env.pop(key, None)
        self.zenoh_configs: dict[str, Path] = {}  # router, agent or "cli" -> its --zenoh-config (use_tls)

    def use_tls(self) -> None:
        """Mutual TLS between the computers, as docs/multi-computer.md says: the certificates made
        on `sim` for the router's address there, each computer holding only its own files."""
        sim = self.lan.hosts["sim"].address
        certs = self.root / "certs"
        spec = str(self.root / "lan.yaml")
        made = subprocess.run(
            [sys.executable, "-m", "fleet", "certs", spec, "--out", str(certs), "--router-address", sim],
            env=self.env,
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert made.returncode == 0, made.stdout + made.stderr
        self.endpoint = f"tls/{sim}:{PORT}"
        self.zenoh_configs = {"router": certs / "router.json5", "cli": certs / "operator-operator.json5"}
        for agent in AGENT_HOSTS:
            computer = self.root / f"computer-{agent}"  # a directory of any name on that computer
            computer.mkdir()
            for name in (f"agent-{agent}.json5", f"{agent}.pem", f"{agent}.key", "ca.pem"):
                shutil.copy(certs / name, computer / name)
            self.zenoh_configs[agent] = computer / f"agent-{agent}.json5"

    def zenoh_config_args(self, role: str) -> list[str]:
        config = self.zenoh_configs.get(role)
        return ["--zenoh-config", str(config)] if config else []

    def spawn(self, key: str, host: str, *args: str) -> None:
        with open(self.root / f"{key}.log", "ab") as log:
            self.processes[key] = subprocess.Popen(
                self.lan.hosts[host].command(sys.executable, "-m", "fleet", *args),
                env=self.env,
                cwd=self.root,
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
            )

    def start(self) -> None:
        self.start_router()
        self.start_agents("sim_host", "rack_a", "rack_b")

    def start_router(self) -> None:
        router_dir = str(self.root / "router")
        self.spawn(
            "router",
            "sim",
            "router",
            "--listen",
            self.endpoint,
            "--state-dir",
            router_dir,
            *self.zenoh_config_args("router"),
        )

    def start_agents(self, *agents: str) -> None:
        """Agents by name; each runs on the computer AGENT_HOSTS names."""
        for agent in agents:
            host = AGENT_HOSTS[agent]
            self.spawn(
                agent,
                host,
                "agent",
                "--name",
                agent,
                "--connect",
                self.endpoint,
                "--state-dir",
                str(self.root / "agents" / agent),
                *self.zenoh_config_args(agent),
            )

    def stop_agent(self, agent: str) -> None:
        """Stop an agent as its computer would on shutdown (its robots stop with it)."""
        process = self.processes[agent]
        process.terminate()
        process.wait(timeout=40)

    def restart_agent(self, agent: str) -> None:
        """Stop an agent and start it again on its state."""
        self.stop_agent(agent)
        self.start_agents(agent)

    def fleet(self, *args: str, timeout: float = 180) -> subprocess.CompletedProcess:
        command = [sys.executable, "-m", "fleet", *args, "--connect", self.endpoint, *self.zenoh_config_args("cli")]
        return subprocess.run(
            self.lan.hosts["sim"].command(*command),
            env=self.env,
            capture_output=True,
            text=True,
            timeout=timeout,
        )

    def status(self) -> dict:
        """`fleet status --json` (it exits 1 when not all runs, and still prints the status)."""
        done = self.fleet("status", "--json", timeout=60)
        if not done.stdout.strip():
            raise AssertionError(f"fleet status printed nothing: {done.stderr.strip()}")
        return json.loads(done.stdout)

    def robots(self) -> dict[str, dict]:
        return {row["name"]: row for row in self.status()["robots"]}

    def wait(self, predicate, timeout: float, what: str):
        """Until predicate(robots) holds for the robots in `fleet status`; returns those robots."""
        return poll(
            self.robots,
            until=predicate,
            timeout=timeout,
            interval=0.5,
            what=what,
            describe=lambda robots: f"robots: {states(robots)}",
            explain=self.log_tails,
        )

    def log_tails(self, lines: int = 15) -> str:
        parts = []
        logs = [self.root / f"{key}.log" for key in self.processes]
        logs += sorted((self.root / "agents").glob("*/services/*.bridge.log"))
        for path in logs:
            text = path.read_text(errors="replace").splitlines()[-lines:] if path.exists() else []
            parts.append(f"--- {path.relative_to(self.root)} ---\n" + "\n".join(text))
        return "\n".join(parts)

    def stop(self) -> None:
        agents = [key for key in self.processes if key != "router"]
        for key in [*agents, "router"]:
            process = self.processes[key]
            if process.poll() is None:
                process.terminate()
            try:
                process.wait(timeout=40)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()

    def stop_and_expect_nothing_left(self) -> None:
        self.stop()
        # Everything the router and agents started (nodes, worlds, discovery servers) carries this
        # test's marker (conftest) through `ip netns exec`: stopping them must have ended it all.
        poll(
            lambda: processes_marked(os.environ[MARKER_VARIABLE]),
            until=lambda leftovers: not leftovers,
            timeout=10,
            interval=0.2,
            what="everything the fleet started to end",
            describe=lambda leftovers: "left running: " + "; ".join(" ".join(p.cmdline()[:6]) for p in leftovers),
        )


@pytest.fixture(params=["dds", "zenoh"])
def fleet(request, lan, tmp_path, ros_domain):
    spec = dict(SPEC, ros={"domain_id": ros_domain, "use_sim_time": True, "transport": request.param})
    (tmp_path / "lan.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    running = Fleet(lan, tmp_path)
    running.transport = request.param
    running.start()
    try:
        yield running
    finally:
        running.stop_and_expect_nothing_left()


@pytest.fixture
def tls_fleet(lan, tmp_path, ros_domain):
    """The LAN's fleet with mutual TLS between its computers, on the `zenoh` transport (the one
    whose ROS data goes through the router, under the same TLS)."""
    spec = dict(SPEC, ros={"domain_id": ros_domain, "use_sim_time": True, "transport": "zenoh"})
    (tmp_path / "lan.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    running = Fleet(lan, tmp_path)
    running.transport = "zenoh"
    running.use_tls()
    running.start()
    try:
        yield running
    finally:
        running.stop_and_expect_nothing_left()


@pytest.fixture
def router_only(lan, tmp_path, ros_domain):
    """The LAN with only its router up (transport dds); the test starts the agents."""
    spec = dict(SPEC, ros={"domain_id": ros_domain, "use_sim_time": True, "transport": "dds"})
    (tmp_path / "lan.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    running = Fleet(lan, tmp_path)
    running.start_router()
    try:
        yield running
    finally:
        running.stop_and_expect_nothing_left()


def states(robots: dict[str, dict]) -> dict[str, tuple[str, str]]:
    return {name: (row["state"], row.get("reason", "")) for name, row in robots.items()}


def poses(robots: dict[str, dict]) -> dict[str, tuple[float, float]]:
    return {name: (row["pose"]["x"], row["pose"]["y"]) for name, row in robots.items() if row.get("pose")}


def moved(before, after, name, distance=0.2) -> bool:
    (x0, y0), (x1, y1) = before[name], after[name]
    return (x1 - x0) ** 2 + (y1 - y0) ** 2 > distance**2


def test_fleet_across_three_computers(fleet, tmp_path):
    # Agents need a moment to reach the router; deploy waits for robots, not for agents.
    agents = poll(
        lambda: {row["name"]: row for row in fleet.status()["agents"] if row["online"]},
        until=lambda online: set(online) >= {"sim_host", "rack_a", "rack_b"},
        timeout=60,
        interval=0.5,
        retry_on=(AssertionError,),  # the router is not listening yet
        what="the three agents online",
    )
    assert agents["rack_a"]["address"] == fleet.lan.hosts["rack_a"].address

    deploy = fleet.fleet("deploy", str(tmp_path / "lan.yaml"), "--timeout", "150")
    assert deploy.returncode == 0, deploy.stdout + deploy.stderr + fleet.log_tails()
    assert "fleet up" in deploy.stdout
    status = fleet.status()
    servers = {d["agent"]: d for d in status["discovery"]["lan"]}
    if fleet.transport == "dds":  # one server, on the world's computer, for every participant
        assert list(servers) == ["sim_host"] and servers["sim_host"]["pid"]
        assert servers["sim_host"]["server"].startswith(fleet.lan.hosts["sim"].address + ":")
    else:  # DDS stays on each computer; every agent bridges what crosses
        assert set(servers) == {"sim_host", "rack_a", "rack_b"}
        assert all(d["server"].startswith("127.0.0.1:") and d["pid"] for d in servers.values())
        assert set(status["bridges"]["lan"]) == {"sim_host", "rack_a", "rack_b"} and all(
            status["bridges"]["lan"].values()
        )
    assert {row["name"]: row["state"] for row in status["robots"]} == dict.fromkeys(("world", *ROBOTS), "running")

    # ROS tools on rack_a, with `fleet ros-env`, see the graph: all of it with dds; with zenoh
    # only this computer's DDS (a1's and a2's nodes, and what the bridge brings in for them).
    args = ["ros-env"] + ([] if fleet.transport == "dds" else ["--agent", "rack_a"])
    exports = fleet.fleet(*args)
    assert exports.returncode == 0 and exports.stdout.startswith("export "), exports.stdout + exports.stderr
    tool_env = dict(pair.split("=", 1) for pair in exports.stdout.split()[1:])
    graph = subprocess.run(
        fleet.lan.hosts["rack_a"].command(sys.executable, "-c", LIST_TOPICS),
        env={**fleet.env, **tool_env},
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert "/a1/odom" in graph.stdout and "/clock" in graph.stdout, graph.stdout + graph.stderr
    assert ("/b1/cmd_vel" in graph.stdout) == (fleet.transport == "dds"), graph.stdout

    # Every robot moves.  a1 and b1 may have met by now (the checks above take seconds), and b1,
    # which has no safety node, keeps pushing a1 back towards (even past) a1's spawn pose: b1 is
    # measured from where it was spawned; a1's driving shows below (its safety node stops it).
    spawned = {robot["name"]: (robot["pose"]["x"], robot["pose"]["y"]) for robot in SPEC["robots"]}
    before = poses(fleet.robots())
    after = fleet.wait(
        lambda robots: all(moved(before, poses(robots), name) for name in ("a2", "b2")),
        30,
        "the patrolling robots on both racks to move",
    )
    assert moved(spawned, poses(after), "b1", 0.1), poses(after)

    # a1 (rack_a) sees b1 (rack_b) on its lidar and its safety node stops it; b1 bumps into a1.
    def met(robots):
        world = fleet.status()["worlds"][0]
        return any({c["a"], c["b"]} == {"a1", "b1"} for c in world["contacts"]["last"])

    fleet.wait(met, 40, "b1 to bump into a1")
    logs = fleet.fleet("logs", "a1", "safety", "--tail", "50", timeout=60)
    assert logs.returncode == 0 and "blocked: obstacle" in logs.stdout, logs.stdout + logs.stderr
    # a1's nodes share one process (isolation: robot): the safety node's own lines only
    # (and its process's start, under the process's name: it hosts them all)
    loggers = {logger for line in logs.stdout.splitlines() if (logger := logger_of(line)) is not None}
    nodes = {logger for logger in loggers if not is_launch_logger(logger)}
    assert nodes and all(belongs_to(logger, "a1.safety") for logger in nodes), logs.stdout
    assert loggers - nodes <= {"composite-1"}, logs.stdout

    # Parameters and logs of a robot on another computer.
    done = fleet.fleet("param", "set", "b2", "controller", "max_speed", "0.7", timeout=90)
    assert done.returncode == 0, done.stdout + done.stderr
    done = fleet.fleet("param", "get", "b2", "controller", "max_speed", timeout=90)
    assert done.returncode == 0 and "0.7" in done.stdout, done.stdout + done.stderr

    # A restart of a robot on another computer: new processes, running again, its live parameter kept.
    old_pids = {node["pid"] for node in fleet.robots()["b2"]["nodes"]}
    done = fleet.fleet("restart", "b2", "--json", "--timeout", "90", timeout=120)
    assert done.returncode == 0 and json.loads(done.stdout)["ok"], done.stdout + done.stderr
    b2 = fleet.robots()["b2"]
    assert b2["state"] == "running" and b2["restarted"] == 1, b2
    assert old_pids and not old_pids & {node["pid"] for node in b2["nodes"]}, (old_pids, b2["nodes"])
    done = fleet.fleet("param", "get", "b2", "controller", "max_speed", timeout=90)
    assert done.returncode == 0 and "0.7" in done.stdout, done.stdout + done.stderr

    # A frozen world: no /clock, no odom; every robot degraded, with the reason; then back.
    world_pid = next(node["pid"] for row in fleet.status()["robots"] if row["name"] == "world" for node in row["nodes"])
    os.kill(world_pid, signal.SIGSTOP)
    try:
        frozen = fleet.wait(
            lambda robots: all(robots.get(name, {}).get("state") == "degraded" for name in ROBOTS),
            15,
            "every robot degraded while the world is frozen",
        )
        assert all("/clock" in frozen[name]["reason"] for name in ROBOTS), frozen
        table = fleet.fleet("status")
        assert table.returncode != 0 and "degraded" in table.stdout and "/clock" in table.stdout, table.stdout
        # A deploy meanwhile does not say "fleet up": it names who is not running and why.
        deploy = fleet.fleet(
            "deploy", str(tmp_path / "lan.yaml"), "--set", "a2.controller.max_speed=0.3", "--timeout", "8"
        )
        assert deploy.returncode == 1 and "fleet up" not in deploy.stdout, deploy.stdout
        why = " ".join(deploy.stdout.partition("not running:")[2].split())  # rich wraps long lines
        assert "timed out" in deploy.stdout and "a2 " in why and "/clock" in why, deploy.stdout
    finally:
        os.kill(world_pid, signal.SIGCONT)
    fleet.wait(
        lambda robots: all(robots.get(name, {}).get("state") == "running" for name in ROBOTS),
        30,
        "every robot running again once the world runs",
    )

    # A pulled cable: rack_b's robots stop being running, with the reason; back when plugged in.
    # Twice: after the first time, the router closing rack_b's dead links answered nothing for
    # about 10 s in most runs, and `fleet status` must wait that out, not fail.
    for _ in range(2):
        fleet.lan.set_link("rack_b", False)
        try:
            cut = fleet.wait(
                lambda robots: all(robots.get(name, {}).get("state", "running") != "running" for name in ("b1", "b2")),
                30,
                "rack_b's robots shown not running while its cable is out",
            )
            assert all(cut[name]["reason"] for name in ("b1", "b2")), cut
            assert cut["a2"]["state"] == "running", (cut["a2"]["state"], cut["a2"].get("reason"))
        finally:
            fleet.lan.set_link("rack_b", True)
        fleet.wait(
            lambda robots: all(robots.get(name, {}).get("state") == "running" for name in ROBOTS),
            60,
            "rack_b's robots running again once its cable is back",
        )


def test_a_fleet_across_computers_over_mutual_tls(tls_fleet, tmp_path):
    """docs/multi-computer.md's TLS steps: certificates for the router's address, each agent with
    its own files only, the CLI with an operator's; robots on both racks drive in the world on
    `sim`, and a parameter reaches a robot on another computer."""
    fleet = tls_fleet
    poll(
        lambda: {row["name"] for row in fleet.status()["agents"] if row["online"]},
        until=lambda online: online >= {"sim_host", "rack_a", "rack_b"},
        timeout=60,
        interval=0.5,
        retry_on=(AssertionError,),  # the router is not listening yet
        what="the three agents online over TLS",
    )
    deploy = fleet.fleet("deploy", str(tmp_path / "lan.yaml"), "--timeout", "150")
    assert deploy.returncode == 0 and "fleet up" in deploy.stdout, deploy.stdout + deploy.stderr + fleet.log_tails()
    before = poses(fleet.robots())
    fleet.wait(
        lambda robots: all(moved(before, poses(robots), name) for name in ("a2", "b2")),
        30,
        "the patrolling robots on both racks to move",
    )
    done = fleet.fleet("param", "set", "b2", "controller", "max_speed", "0.7", timeout=90)
    assert done.returncode == 0, done.stdout + done.stderr
    # Without the operator's configuration the router's TLS endpoint takes no session.
    plain = subprocess.run(
        fleet.lan.hosts["sim"].command(sys.executable, "-m", "fleet", "status", "--connect", fleet.endpoint),
        env=fleet.env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert plain.returncode == 1 and "cannot reach the fleet router" in plain.stderr, plain.stdout + plain.stderr


def test_deploy_before_the_agents_are_up(router_only, tmp_path):
    """kubectl-style: the desired state waits at the router.  No agent is online to tell where the
    fleet's DDS discovery server will run, so its host (the world's agent) runs it at its own
    address once up, and the other agents find that address then: started before it, their
    robots first run without the server and are restarted with it.  An agent started again
    later keeps that address: its robots get the server at once, even with the host down."""
    fleet = router_only
    deploy = poll(
        lambda: fleet.fleet("deploy", str(tmp_path / "lan.yaml"), "--no-wait", timeout=60),
        until=lambda done: "unreachable" in done.stdout + done.stderr,
        timeout=30,
        interval=0.5,
        what="a deploy the router takes while no agent is up",
        describe=lambda done: done.stdout + done.stderr,
    )
    assert deploy.returncode != 0, deploy.stdout
    assert "sim_host runs" in " ".join(deploy.stdout.split()), deploy.stdout

    fleet.start_agents("rack_a", "rack_b")
    fleet.wait(
        lambda robots: all(robots.get(name, {}).get("state") not in (None, "pending") for name in ROBOTS),
        60,
        "the racks' agents to fetch their robots from the router",
    )
    fleet.start_agents("sim_host")
    robots = fleet.wait(
        lambda robots: all(robots.get(name, {}).get("state") == "running" for name in ("world", *ROBOTS)),
        120,
        "every robot running once the world's agent is up",
    )
    assert set(robots) == {"world", *ROBOTS}
    servers = {d["agent"]: d["server"] for d in fleet.status()["discovery"]["lan"]}
    assert servers == {"sim_host": f"{fleet.lan.hosts['sim'].address}:{servers['sim_host'].rpartition(':')[2]}"}
    # A deploy now (every agent online) would give them the address they found: nothing restarts.
    diff = fleet.fleet("diff", str(tmp_path / "lan.yaml"), "--json")
    assert diff.returncode == 0, diff.stdout + diff.stderr
    assert {row["change"] for row in json.loads(diff.stdout)} == {"unchanged"}, diff.stdout

    # The world's computer and rack_b go down, and rack_b comes back first: it starts its robots
    # with the server the host gave it before (not confined to rack_b until the host answers),
    # and they keep running, not restarted, when the host is back.
    fleet.stop_agent("sim_host")
    fleet.restart_agent("rack_b")
    back = fleet.wait(
        lambda robots: all(
            robots.get(name, {}).get("nodes") and all(node.get("pid") for node in robots[name]["nodes"])
            for name in ("b1", "b2")
        ),
        60,
        "rack_b's robots started again while the world's agent is down",
    )
    pids = node_pids(back, "b1", "b2")
    for pid in (pid for group in pids.values() for pid in group):
        assert psutil.Process(pid).environ().get("ROS_DISCOVERY_SERVER") == servers["sim_host"], pid
    fleet.start_agents("sim_host")
    robots = fleet.wait(
        lambda robots: all(robots.get(name, {}).get("state") == "running" for name in ("world", *ROBOTS)),
        120,
        "every robot running once the world's agent is back",
    )
    assert node_pids(robots, "b1", "b2") == pids


def node_pids(robots: dict[str, dict], *names: str) -> dict[str, list[int]]:
    return {name: sorted(node["pid"] for node in robots[name]["nodes"]) for name in names}
