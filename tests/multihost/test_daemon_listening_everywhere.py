"""`fleet up --listen tcp/0.0.0.0:PORT` on a workstation takes agents of other computers: its own
agent then reports the workstation's LAN address, which other computers' nodes are sent to (the
discovery server of a `dds` fleet runs there), not 127.0.0.1.  Two computers are network
namespaces (fleet.testing.netns); the one on which the daemon runs has no default route, as on
an isolated robot LAN."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import psutil
import pytest

from fleet.client.local_daemon import running_pid
from fleet.testing.netns import Lan, netns_problem

pytestmark = pytest.mark.integration

PORT = 7447  # each computer (namespace) has its own ports


def test_a_daemon_listening_on_every_interface_reports_its_lan_address(tmp_path):
    problem = netns_problem()
    if problem:
        pytest.skip(problem)
    state = tmp_path / "state"
    env = dict(os.environ, FLEET_STATE_DIR=str(state), ROS_HOME=str(tmp_path / "ros"))
    for key in ("FLEET_CONNECT", "FLEET_ZENOH_CONFIG", "ROS_DISCOVERY_SERVER"):
        env.pop(key, None)
    with Lan(["ws", "rack"]) as lan:
        ws, rack = lan.hosts["ws"], lan.hosts["rack"]

        def fleet(host, *args: str) -> subprocess.CompletedProcess:
            command = host.command(sys.executable, "-m", "fleet", *args)
            return subprocess.run(command, env=env, capture_output=True, text=True, timeout=60)

        try:
            up = fleet(ws, "up", "--listen", f"tcp/0.0.0.0:{PORT}")
            assert up.returncode == 0, up.stdout + up.stderr
            # Asked from the other computer, through the workstation's LAN address.
            status = fleet(rack, "status", "--json", "--connect", f"tcp/{ws.address}:{PORT}")
            assert status.returncode == 0, status.stdout + status.stderr
            agents = json.loads(status.stdout)["agents"]
            assert [(agent["name"], agent["address"]) for agent in agents] == [("local", ws.address)]
        finally:
            down = fleet(ws, "down", "--all")
            pid = running_pid(state)
            if pid is not None and psutil.pid_exists(pid):  # `down` failed: leave nothing running
                psutil.Process(pid).kill()
    assert down.returncode == 0, down.stdout + down.stderr
