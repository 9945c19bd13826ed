"""fleet's own ROS helpers write no rcl log file.

The agent runs a parameter helper for every `fleet param` command and a graph watch per fleet
(and a bridge): rcl made a log file for each of their processes in ~/.ros/log (the agent does not
give them a ROS_LOG_DIR of their own), one more per command, which nothing ever removed.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from fleet.testing.poll import poll

pytestmark = pytest.mark.integration


def test_a_parameter_call_leaves_no_rcl_log_file(ros_env, tmp_path):
    logs = tmp_path / "ros-log"
    env = {**os.environ, "ROS_LOG_DIR": str(logs)}
    done = subprocess.run(
        [sys.executable, "-m", "fleet.runtime.param_helper", "list"],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert json.loads(done.stdout.splitlines()[-1])["ok"], done.stderr
    assert not logs.exists() or list(logs.iterdir()) == []


def test_the_graph_watch_leaves_no_rcl_log_file(ros_env, tmp_path):
    logs = tmp_path / "ros-log"
    status = tmp_path / "watch.status.json"
    config = tmp_path / "watch.json"
    config.write_text(json.dumps({"fleet": "f", "topics": ["/clock"], "nodes": True, "status_file": str(status)}))
    env = {**os.environ, "ROS_LOG_DIR": str(logs)}
    watch = subprocess.Popen([sys.executable, "-m", "fleet.dataplane.watch", str(config)], env=env)
    try:
        poll(status.exists, timeout=60, interval=0.1, what="the watch's first report")
    finally:
        watch.send_signal(signal.SIGTERM)
        watch.wait(timeout=30)
    assert not logs.exists() or list(logs.iterdir()) == []
