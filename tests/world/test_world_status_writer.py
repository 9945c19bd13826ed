"""The status file written by the world's status writer process, and the writer's lifetime."""

import contextlib
import json
import math
import os
import signal
import subprocess
import sys

import numpy as np
import psutil

from fleet.world.app import WorldApp
from fleet.world.status import finish_status
from fleet.world.status_writer import StatusWriter

# The writer is a Python process of its own: on a loaded machine (a suite beside another) its
# start took more than the 5 s the world waits at most, and a status was then not yet written.
STARTED = 60.0


def parts(sim_time: float) -> dict:
    ranges = np.array([1.0, np.inf, 2.0, 0.5])
    robot = {
        "pose": {"x": 1.0, "y": 2.0, "yaw": 0.0},
        "trail": [(1.0, 2.0)],
        "hits": (1.0, 2.0, 0.0, -math.pi, math.pi / 2, ranges),
    }
    return {"fleet": "f", "sim_time": sim_time, "robots": {"r1": robot}}


def test_writer_writes_the_finished_document_and_ends_when_closed(tmp_path):
    path = tmp_path / "status.json"
    writer = StatusWriter(path)
    try:
        assert writer.submit(parts(1.5))
        writer.settle(STARTED)
        written = json.loads(path.read_text())
        assert written == json.loads(json.dumps(finish_status(parts(1.5))))
        assert written["robots"]["r1"]["scan_hits"] == [[0.0, 2.0], [3.0, 2.0], [1.0, 2.5]]
        assert "hits" not in written["robots"]["r1"]
        assert writer.submit(parts(2.0))
    finally:
        writer.close(STARTED)
    assert json.loads(path.read_text())["sim_time"] == 2.0  # the status in flight was written first
    assert writer._child.poll() == 0


def test_a_ctrl_c_while_the_writer_starts_does_not_reach_it(tmp_path):
    """Ctrl-C reaches the world's whole process group; the world stops the writer itself.  One in
    the writer's first moments, before its Python had set SIGINT aside, ended it (a traceback
    from its imports)."""
    path = tmp_path / "status.json"
    writer = StatusWriter(path)
    try:
        os.kill(writer._child.pid, signal.SIGINT)  # at once: its Python is still starting
        assert writer.submit(parts(1.0))
        writer.settle(STARTED)
        assert json.loads(path.read_text())["sim_time"] == 1.0
    finally:
        writer.close(STARTED)
    assert writer._child.poll() == 0


PARENT = """
import sys, time
from fleet.world.status_writer import StatusWriter
writer = StatusWriter(sys.argv[1])
print(writer._child.pid, flush=True)
time.sleep(600)
"""


def test_writer_dies_with_a_killed_world_even_when_it_cannot_read_the_closed_pipe(tmp_path):
    # A writer still starting up (slow under load) or stopped does not see the pipe close: the
    # kernel must end it when the world dies, or it outlives the fleet.
    parent = subprocess.Popen([sys.executable, "-c", PARENT, str(tmp_path / "status.json")], stdout=subprocess.PIPE)
    try:
        assert parent.stdout is not None
        child = psutil.Process(int(parent.stdout.readline()))
        child.suspend()
        parent.kill()
        parent.wait()
        _, alive = psutil.wait_procs([child], timeout=10)
        assert not alive, "the status writer outlived the world it writes for"
    finally:
        parent.kill()
        parent.wait()
        with contextlib.suppress(psutil.NoSuchProcess):
            child.kill()


def test_a_world_stopped_before_it_ran_starts_no_writer(tmp_path):
    config = tmp_path / "world.yaml"
    config.write_text("fleet: test\nrobots:\n- {name: robot1, pose: {x: 0.0, y: 0.0}}\n")
    app = WorldApp(config, tmp_path / "status.json", as_fast_as_possible=True)
    try:
        app.stopping = True  # a SIGTERM during start-up
        app.run()
        assert app._writer is None
        assert json.loads((tmp_path / "status.json").read_text())["stopped"] is True
    finally:
        app.close()
