"""A `zenoh`-transport bridge probes its path through the router every second: the fleet router
echoes each probe, and a bridge whose router is connected but echoes nothing for 5 s opens a new
Zenoh session (a reconnected session was seen to carry nothing, see fleet.dataplane.bridge)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fleet.dataplane.bridge import ECHO_TIMEOUT
from fleet.testing.isolation import free_tcp_port
from fleet.testing.poll import poll
from fleet.wire import protocol as p

pytestmark = pytest.mark.integration

REPLACED = "has not echoed this bridge"


def start_bridge(tmp_path: Path, endpoint: str, env: dict[str, str]) -> tuple[subprocess.Popen, Path]:
    config = tmp_path / "lan.bridge.json"
    config.write_text(
        json.dumps(
            {
                "fleet": "lan",
                "agent": "rack_a",
                "connect": [endpoint],
                "zenoh_config": None,
                "exports": [],
                "imports": [],
            }
        )
    )
    log = tmp_path / "bridge.log"
    with open(log, "wb") as out:
        process = subprocess.Popen(
            [sys.executable, "-m", "fleet.dataplane.bridge", str(config)],
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
        )
    return process, log


def stop(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(timeout=20)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()


def test_the_fleet_router_echoes_and_the_bridge_keeps_its_session(fresh_cluster, tmp_path, ros_env):
    cluster = fresh_cluster
    cluster.start_router()
    ping, pong = p.echo_keys("lan", "rack_a")
    with cluster.client() as client:  # the router puts a ping back on the pong key
        echoes = []
        subscriber = client.session.declare_subscriber(pong, lambda sample: echoes.append(sample.payload.to_bytes()))
        poll(lambda: client.session.put(ping, b"hello") or echoes, until=bool, timeout=10, what="an echo")
        assert echoes[0] == b"hello"
        subscriber.undeclare()
    bridge, log = start_bridge(tmp_path, cluster.endpoint, ros_env)
    try:
        poll(
            lambda: log.read_text(), until=lambda text: "bridge of fleet lan" in text, timeout=60, what="the bridge up"
        )
        time.sleep(ECHO_TIMEOUT + 3)  # longer than a bridge waits for an echo
        assert bridge.poll() is None and REPLACED not in log.read_text(), log.read_text()
    finally:
        stop(bridge)


def test_a_bridge_whose_router_echoes_nothing_opens_a_new_session(tmp_path, ros_env):
    """A plain Zenoh router (real, but without the fleet router's echo) stands for a router path
    that has silently stopped carrying this bridge's data."""
    import zenoh

    endpoint = f"tcp/127.0.0.1:{free_tcp_port()}"
    config = zenoh.Config()
    config.insert_json5("mode", '"router"')
    config.insert_json5("listen/endpoints", json.dumps([endpoint]))
    config.insert_json5("scouting/multicast/enabled", "false")
    with zenoh.open(config):
        bridge, log = start_bridge(tmp_path, endpoint, ros_env)
        try:
            text = poll(log.read_text, until=lambda text: REPLACED in text, timeout=60, what="the session replaced")
            assert "bridge of fleet lan" in text
            assert bridge.poll() is None  # it goes on, on its new session
        finally:
            stop(bridge)
