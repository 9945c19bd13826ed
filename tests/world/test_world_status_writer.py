"""The status file written by the world's status writer process."""

import json
import math

import numpy as np

from fleet.world.status import finish_status
from fleet.world.status_writer import StatusWriter


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
        writer.settle()
        written = json.loads(path.read_text())
        assert written == json.loads(json.dumps(finish_status(parts(1.5))))
        assert written["robots"]["r1"]["scan_hits"] == [[0.0, 2.0], [3.0, 2.0], [1.0, 2.5]]
        assert "hits" not in written["robots"]["r1"]
        assert writer.submit(parts(2.0))
    finally:
        writer.close()
    assert json.loads(path.read_text())["sim_time"] == 2.0  # the status in flight was written first
    assert writer._child.poll() == 0
