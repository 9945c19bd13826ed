"""The host process's spinning (fleet.nodes.host.Host), in a context of the test's own."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from fleet.nodes.host import Host
from fleet.runtime.hosting import host_environment


def test_one_wait_serves_every_callback_ready_together(ros):
    """A host of 25 robots on sim time has 75 nodes with a /clock subscription each: every wait
    must serve all the callbacks it found ready, not be rebuilt over every entity for each one
    (rebuilt per callback, the host fell behind /clock and its robots never started driving)."""
    import rclpy

    host = Host(context=ros.context)
    node = rclpy.create_node("many_timers", context=ros.context)
    fired: list[int] = []
    for index in range(20):
        node.create_timer(0.001, lambda index=index: fired.append(index))  # all due at every wait
    host.executor.add_node(node)
    waits = 0  # each spin_once is one wait
    try:
        time.sleep(0.01)
        while len(fired) < 200 and waits < 200:
            host.spin_once()
            waits += 1
        assert len(fired) >= 200
        assert waits <= 40, f"{waits} waits for 200 callbacks of 20 timers due together"
    finally:
        host.executor.remove_node(node)
        node.destroy_node()
        host.executor.shutdown()


def test_a_robot_failing_in_a_young_host_is_made_again_only_once_the_host_is_a_few_seconds_old(ros):
    """Made and destroyed again and again in a participant the discovery server has only just
    met, a failing robot's nodes can cost another robot of the host its discovery for good
    (docs/architecture.md, "Known problem"): its retries wait until the host is YOUNG seconds old.
    An older host retries after the runner's backoff alone."""
    from fleet.nodes.host import YOUNG, HostedRobot

    host = Host(context=ros.context)
    try:
        young = HostedRobot(name="robot2", nodes=[], respawn_delay=0.1)
        host.after_failure(young)
        assert young.state == "backoff" and young.restart_at is not None
        assert young.restart_at >= host.started_at + YOUNG
        host.started_at -= YOUNG
        older = HostedRobot(name="robot3", nodes=[], respawn_delay=0.1)
        asked = time.monotonic()
        host.after_failure(older)
        assert older.restart_at is not None and older.restart_at - asked < 1.0
    finally:
        host.executor.shutdown()


def test_a_robots_failure_and_restart_import_nothing(ros_env, tmp_path):
    """The host's executor thread carries out a robot's failure: whatever it waits for, every other
    robot of the host waits for.  Its first failure imported fleet.rules and fleet.runtime.supervisor
    there (0.28 s): the neighbours' cmd_vel stopped for longer than the world's command timeout.
    A host imports at start-up all that a robot's failure and restart need."""
    with tempfile.TemporaryDirectory(prefix="fleet-host-") as sockets:  # a Unix socket path is short
        done = subprocess.run(
            [sys.executable, "-m", "tests.nodes.failing_host", str(Path(sockets) / "host.sock")],
            cwd=Path(__file__).parents[2],
            env=host_environment(os.environ, tmp_path),
            capture_output=True,
            text=True,
            timeout=90,
        )
    assert done.returncode == 0, done.stderr[-3000:]
    imported = json.loads(done.stdout.splitlines()[-1])
    assert imported == [], f"a robot's failure imported {imported}"
