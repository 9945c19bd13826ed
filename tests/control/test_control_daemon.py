"""The embedded default: `fleet deploy` starts a local daemon, `fleet down --all` stops it."""

from __future__ import annotations

import json

import psutil
import pytest

from fleet.client.local_daemon import running_pid
from tests.control.control_helpers import wait_processes_gone

pytestmark = pytest.mark.integration


def test_deploy_starts_the_local_daemon_and_down_all_stops_it(fresh_cluster, tmp_path):
    cluster = fresh_cluster
    state = tmp_path / "state"
    env = dict(cluster.env, FLEET_STATE_DIR=str(state), FLEET_CONNECT=cluster.endpoint)
    spec = cluster.spec(
        agents={"local": {}},
        defaults={"template": "tiny", "agent": "local"},
        robots=[{"name": "robot1"}, {"name": "robot2"}],
    )
    try:
        done = cluster.cli("deploy", str(spec), env=env)
        assert done.returncode == 0, done.stdout + done.stderr
        assert "starting the local fleet daemon" in done.stderr
        pid = running_pid(state)
        assert pid is not None and (state / "daemon.log").exists()
        assert (state / "agents" / "local" / "desired" / "tiny.json").exists()

        status = cluster.cli("status", "--json", env=env)
        assert status.returncode == 0, status.stdout + status.stderr
        robots = json.loads(status.stdout)["robots"]
        assert {(r["name"], r["agent"], r["state"]) for r in robots} == {
            ("robot1", "local", "running"),
            ("robot2", "local", "running"),
        }
        node_pids = {node["pid"] for r in robots for node in r["nodes"]}

        again = cluster.cli("up", env=env)
        assert again.returncode == 0 and f"pid {pid}" in again.stdout

        down = cluster.cli("down", "--all", env=env)
        assert down.returncode == 0, down.stdout + down.stderr
        assert "local daemon stopped" in down.stdout
        wait_processes_gone([pid], 10)
        assert not any(psutil.pid_exists(p) for p in node_pids)
        assert running_pid(state) is None and not (state / "daemon.pid").exists()
    finally:
        cluster.cli("down", "--all", env=env)
