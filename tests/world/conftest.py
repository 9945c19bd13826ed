"""A real world process (`python -m fleet.nodes.world`) in the test's own ROS domain."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.fixture
def start_world(tmp_path, ros_env):
    """start_world(world_yaml_text, *options) -> (config, status file, process).  The world is
    stopped with SIGINT at the end of the test (killed if it does not stop) and its log printed."""
    started: list[tuple[subprocess.Popen, Path]] = []

    def start(text: str, *options: str) -> tuple[Path, Path, subprocess.Popen]:
        config, status = tmp_path / "world.yaml", tmp_path / "status.json"
        config.write_text(text)
        log = tmp_path / "world.log"  # a file, not a pipe: a full pipe would block the world
        command = [sys.executable, "-m", "fleet.nodes.world", "--config", str(config), "--status-file", str(status)]
        with open(log, "w") as out:
            process = subprocess.Popen([*command, *options], env=ros_env, stdout=out, stderr=subprocess.STDOUT)
        started.append((process, log))
        return config, status, process

    yield start
    for process, log in started:
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        print(log.read_text()[-4000:])
