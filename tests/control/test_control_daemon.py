"""The embedded default: `fleet deploy` starts a local daemon, `fleet down --all` stops it."""

from __future__ import annotations

import json

import psutil
import pytest

from fleet.client.local_daemon import running_pid
from fleet.testing.isolation import free_tcp_port
from fleet.testing.poll import poll
from tests.control.control_helpers import wait_processes_gone

pytestmark = pytest.mark.integration


def test_deploy_starts_the_local_daemon_and_down_all_stops_it(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    state = tmp_path / "state"
    # Relative, as a user may set it: the daemon's agent leaves the working directory, and
    # every file of the daemon must still land in this one.
    env = dict(cluster.env, FLEET_STATE_DIR="state", FLEET_CONNECT=cluster.endpoint)

    def fleet(*args: str):
        return cluster.cli(*args, env=env, cwd=tmp_path)

    spec = cluster.spec(
        agents={"local": {}},
        defaults={"template": "tiny", "agent": "local"},
        robots=[{"name": "robot1"}, {"name": "robot2"}],
    )
    try:
        done = fleet("deploy", str(spec))
        assert done.returncode == 0, done.stdout + done.stderr
        assert "starting the local fleet daemon" in done.stderr
        pid = running_pid(state)
        assert pid is not None and (state / "daemon.log").exists()
        assert (state / "agents" / "local" / "desired" / "tiny.json").exists()
        assert (state / "router" / "registry.json").exists()
        assert [path.relative_to(state) for path in state.rglob("state")] == []

        status = fleet("status", "--json")
        assert status.returncode == 0, status.stdout + status.stderr
        robots = json.loads(status.stdout)["robots"]
        assert {(r["name"], r["agent"], r["state"]) for r in robots} == {
            ("robot1", "local", "running"),
            ("robot2", "local", "running"),
        }
        node_pids = {node["pid"] for r in robots for node in r["nodes"]}

        again = fleet("up")
        assert again.returncode == 0 and f"pid {pid}" in again.stdout

        down = fleet("down", "--all")
        assert down.returncode == 0, down.stdout + down.stderr
        assert "local daemon stopped" in down.stdout
        wait_processes_gone([pid], 10)
        assert not any(psutil.pid_exists(p) for p in node_pids)
        assert running_pid(state) is None and not (state / "daemon.pid").exists()
    finally:
        fleet("down", "--all")


def test_up_with_agents_runs_a_spec_for_several_computers_on_this_one(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    state = tmp_path / "state"
    env = dict(cluster.env, FLEET_STATE_DIR=str(state), FLEET_CONNECT=cluster.endpoint)
    spec = cluster.spec(
        agents={"rack_a": {}, "rack_b": {}},
        defaults={"template": "tiny", "agent": "rack_a"},
        robots=[{"name": "robot1"}, {"name": "robot2", "agent": "rack_b"}],
    )
    try:
        # Nothing listens, and the spec is not for the local agent: nothing is started, the error
        # says how to run its agents here.
        refused = cluster.cli("deploy", str(spec), env=env)
        assert refused.returncode == 1 and refused.stdout == "", refused.stdout + refused.stderr
        assert len(refused.stderr.splitlines()) == 1
        assert "`fleet up --agent rack_a --agent rack_b`" in refused.stderr
        assert running_pid(state) is None

        bad = cluster.cli("up", "--agent", "rack/a", env=env)
        assert bad.returncode == 2 and bad.stderr.startswith("fleet: error: --agent rack/a: agent name"), bad.stderr
        assert running_pid(state) is None

        up = cluster.cli("up", "--agent", "rack_a", "-a", "rack_b", env=env)
        assert up.returncode == 0, up.stdout + up.stderr
        assert "with agents local, rack_a, rack_b" in up.stdout
        pid = running_pid(state)
        assert pid is not None

        done = cluster.cli("deploy", str(spec), env=env)
        assert done.returncode == 0, done.stdout + done.stderr
        status = json.loads(cluster.cli("status", "--json", env=env).stdout)
        assert {(r["name"], r["agent"], r["state"]) for r in status["robots"]} == {
            ("robot1", "rack_a", "running"),
            ("robot2", "rack_b", "running"),
        }
        assert {a["name"] for a in status["agents"] if a["online"]} == {"local", "rack_a", "rack_b"}
        node_pids = {node["pid"] for r in status["robots"] for node in r["nodes"]}
        assert all(psutil.Process(p).ppid() == pid for p in node_pids)  # the daemon runs them all

        # A running daemon without an agent asked for is one process with its router: it is
        # started again with that agent too, said so; its fleet comes back on it.
        more = cluster.cli("up", "--agent", "rack_c", env=env)
        assert more.returncode == 0, more.stdout + more.stderr
        assert f"restarting the local daemon (pid {pid}) with agents local, rack_a, rack_b, rack_c" in more.stderr
        assert "with agents local, rack_a, rack_b, rack_c" in more.stdout
        wait_processes_gone([pid, *node_pids], 10)
        pid = running_pid(state)
        assert pid is not None
        status = poll(
            lambda: json.loads(cluster.cli("status", "--json", env=env).stdout),
            until=lambda status: {r["state"] for r in status["robots"]} == {"running"},
            timeout=30,
            what="the fleet running again on the restarted daemon",
        )
        assert {(r["name"], r["agent"]) for r in status["robots"]} == {("robot1", "rack_a"), ("robot2", "rack_b")}
        assert {a["name"] for a in status["agents"] if a["online"]} == {"local", "rack_a", "rack_b", "rack_c"}

        # Started again elsewhere, it keeps its agents (it used to come back with `local` alone,
        # and rack_a's and rack_b's robots offline).
        moved = f"tcp/127.0.0.1:{free_tcp_port()}"
        elsewhere = cluster.cli("up", "--listen", moved, env=env)
        assert elsewhere.returncode == 0, elsewhere.stdout + elsewhere.stderr
        assert f"on {moved} with agents local, rack_a, rack_b, rack_c" in elsewhere.stdout
        wait_processes_gone([pid], 10)
        pid = running_pid(state)
        assert pid is not None
        env["FLEET_CONNECT"] = moved
        status = poll(
            lambda: json.loads(cluster.cli("status", "--json", env=env).stdout),
            until=lambda status: {r["state"] for r in status["robots"]} == {"running"},
            timeout=30,
            what="the fleet running again on the daemon started elsewhere",
        )
        assert {a["name"] for a in status["agents"] if a["online"]} == {"local", "rack_a", "rack_b", "rack_c"}
        node_pids = {node["pid"] for r in status["robots"] for node in r["nodes"]}
        assert all(psutil.Process(p).ppid() == pid for p in node_pids)

        down = cluster.cli("down", "--all", env=env)
        assert down.returncode == 0, down.stdout + down.stderr
        wait_processes_gone([pid], 10)
        assert not any(psutil.pid_exists(p) for p in node_pids)
    finally:
        cluster.cli("down", "--all", env=env)


def test_up_listening_elsewhere_moves_the_daemon_and_commands_say_where_it_is(fresh_cluster, tmp_path):
    """`fleet up --listen` against a daemon running on another endpoint starts it again there
    (it kept the old one, silently); a command without --connect then says where it listens,
    and `fleet down --all` stops its fleets there."""
    cluster = fresh_cluster
    state = tmp_path / "state"
    env = dict(cluster.env, FLEET_STATE_DIR=str(state), FLEET_CONNECT=cluster.endpoint)
    moved = f"tcp/127.0.0.1:{free_tcp_port()}"
    spec = cluster.spec(agents={"local": {}}, defaults={"template": "tiny", "agent": "local"}, robots=[{"name": "r1"}])
    try:
        assert cluster.cli("deploy", str(spec), env=env).returncode == 0
        pid = running_pid(state)
        assert pid is not None

        same = cluster.cli("up", "--listen", cluster.endpoint, env=env)
        assert same.returncode == 0 and same.stderr == "" and running_pid(state) == pid, same.stderr

        up = cluster.cli("up", "--listen", moved, env=env)
        assert up.returncode == 0, up.stdout + up.stderr
        assert f"restarting the local daemon (pid {pid}) on {moved} (it listened on {cluster.endpoint})" in up.stderr
        assert f"on {moved} with agents local" in up.stdout
        wait_processes_gone([pid], 10)
        pid = running_pid(state)
        assert pid is not None

        missed = cluster.cli("status", env=env)
        assert missed.returncode == 1 and missed.stdout == "", missed.stdout + missed.stderr
        assert missed.stderr.splitlines() == [
            f"fleet: error: no fleet router answers at {cluster.endpoint}; the local daemon (pid {pid}) listens "
            f"on {moved}: give --connect {moved} (or set FLEET_CONNECT)"
        ]
        status = poll(
            lambda: json.loads(cluster.cli("status", "--json", "--connect", moved, env=env).stdout),
            until=lambda status: [r["state"] for r in status["robots"]] == ["running"],
            timeout=30,
            what="the fleet running again on the moved daemon",
        )
        node_pids = {node["pid"] for r in status["robots"] for node in r["nodes"]}

        down = cluster.cli("down", "--all", env=env)
        assert down.returncode == 0, down.stdout + down.stderr
        assert "fleet tiny: stopped on 1 agent(s)" in down.stdout and "local daemon stopped" in down.stdout
        wait_processes_gone([pid, *node_pids], 10)

        # Its fleets were stopped, not only its process: a new daemon runs none.
        assert cluster.cli("up", env=env).returncode == 0
        robots = json.loads(cluster.cli("status", "--json", env=env).stdout)["robots"]
        assert robots == []
    finally:
        cluster.cli("down", "--all", env=env)
        cluster.cli("down", "--all", "--connect", moved, env=env)


def test_a_package_the_daemon_started_without_is_named_with_how_to_restart_it(fresh_cluster, tmp_path):
    """The local daemon keeps the environment of the shell that started it: a workspace sourced
    afterwards does not reach its agents, and deploy, refused, says so and what to do."""
    cluster = fresh_cluster
    state = tmp_path / "state"
    env = dict(cluster.env, FLEET_STATE_DIR=str(state), FLEET_CONNECT=cluster.endpoint)
    without = {name: value for name, value in env.items() if name != "AMENT_PREFIX_PATH"}
    spec = cluster.spec(agents={"local": {}}, defaults={"template": "tiny", "agent": "local"}, robots=[{"name": "r1"}])
    try:
        neither = cluster.cli("deploy", str(spec), env=without)
        assert neither.returncode == 2, neither.stdout + neither.stderr
        assert "r1 cannot start on agent local: " in neither.stderr
        assert "package 'fleet_test' not found in the ament index" in neither.stderr
        assert "this shell's lacks fleet_test too: source the workspace that installs it" in neither.stderr
        assert running_pid(state) is not None  # started by that deploy, without the package

        sourced = cluster.cli("deploy", str(spec), env=env)  # the daemon's environment is as it was
        assert sourced.returncode == 2, sourced.stdout + sourced.stderr
        assert f"this shell's has fleet_test (in {cluster.prefix}): `fleet down --all`" in sourced.stderr

        assert cluster.cli("down", "--all", env=env).returncode == 0
        restarted = cluster.cli("deploy", str(spec), env=env)
        assert restarted.returncode == 0, restarted.stdout + restarted.stderr
        assert "hint:" not in restarted.stderr
    finally:
        cluster.cli("down", "--all", env=env)
