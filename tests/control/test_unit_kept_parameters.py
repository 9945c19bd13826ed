"""Whether a value `fleet param set` gives a node comes back from the robot's parameter file when
the node restarts, as the agent reads the unit's own launch file: not when the launch file gives
the parameter inline after the file, nor when it starts the node without the file."""

from __future__ import annotations

import hashlib

from fleet.server.units import Unit
from fleet.wire import protocol as p

LAUNCH = """\
launch:
- node:
    pkg: demo
    exec: sleeper
    name: controller
    param:
    - {from: $(dirname)/robot1.params.yaml}
    - {name: use_sim_time, value: false}
- node:
    pkg: demo
    exec: sleeper
    name: battery
    param:
    - {name: use_sim_time, value: true}
"""


def unit(tmp_path) -> Unit:
    files = {"robot1.launch.yaml": LAUNCH, "robot1.params.yaml": "/controller:\n  ros__parameters: {max_speed: 0.5}\n"}
    bundle = p.BundleMessage(
        name="robot1",
        kind="robot",
        entry="robot1.launch.yaml",
        files=files,
        options={"isolation": "robot"},
        digest=hashlib.sha256(LAUNCH.encode()).hexdigest(),
    )
    made = Unit("f", bundle, tmp_path / "robot1", env={})
    made.write_files({})
    return made


def test_a_value_set_live_is_kept_only_where_the_parameter_file_would_bring_it_back(tmp_path):
    robot = unit(tmp_path)
    assert robot.not_kept_by_file("controller", "max_speed") is None  # the file brings it back
    assert robot.not_kept_by_file("controller", "use_sim_time") == (
        "the launch file gives use_sim_time inline after the parameter file (robot1.launch.yaml:8:7: false), "
        "so a restart brings that value back"
    )
    # The battery reads no file: its inline values come back, and the rest is the node's own.
    assert robot.not_kept_by_file("battery", "use_sim_time") == (
        "the launch file gives use_sim_time inline (robot1.launch.yaml:14:7: true), so a restart brings that value back"
    )
    assert robot.not_kept_by_file("battery", "capacity") == (
        "the launch file starts battery without the robot's parameter file (robot1.launch.yaml:9:3), so a "
        "restart brings the node's own default back"
    )
