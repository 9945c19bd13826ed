"""The world loop without ROS: live reload, spawn refusal in the status, restart from the status
file, and a snapshot drawn from status data."""

import json
import os
import time

import pytest

from fleet.world.app import WorldApp, resume_time
from fleet.world.description import WorldError
from fleet.world.snapshot import draw_snapshot

BASE = """\
fleet: test
obstacles:
- {name: wall, type: box, position: [3.0, 0.0], size: [0.2, 4.0, 1.0]}
- {name: pillar, type: cylinder, position: [0.0, 2.0], radius: 0.3}
robots:
- {name: robot1, pose: {x: 0.0, y: 0.0}}
- {name: robot2, pose: {x: 1.0, y: 0.0, yaw: 1.57}}
"""


def write(path, text):
    path.write_text(text)
    # make sure the mtime/size stamp differs even on coarse filesystem clocks
    stamp = time.time() + 1 + len(text) * 1e-3
    os.utime(path, (stamp, stamp))


@pytest.fixture
def files(tmp_path):
    config = tmp_path / "world.yaml"
    write(config, BASE)
    return config, tmp_path / "status.json"


def test_reload_adds_refuses_and_removes_robots(files):
    config, status_file = files
    app = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        app.run(sim_duration=0.2)
        assert set(app.robots) == {"robot1", "robot2"}
        before = app.physics.robots["robot1"].pose()
        write(
            config, BASE + "- {name: robot3, pose: {x: -2.0, y: 0.0}}\n- {name: robot4, pose: {x: 0.1, y: 2.0}}\n"
        )  # robot4 sits in the pillar
        app.check_reload()
        assert set(app.robots) == {"robot1", "robot2", "robot3"}
        assert app.physics.robots["robot1"].pose() == before  # the others were not disturbed
        app.write_status()
        status = json.loads(status_file.read_text())
        assert len(status["errors"]) == 1 and "robot4" in status["errors"][0]["message"]
        assert "overlaps obstacle 'pillar'" in status["errors"][0]["message"]
        assert set(status["robots"]) == {"robot1", "robot2", "robot3"}

        write(config, "robots: [\n")  # broken: reported, the world keeps what it has
        app.check_reload()
        assert set(app.robots) == {"robot1", "robot2", "robot3"}
        assert any("not applied" in e["message"] for e in app.status()["errors"])

        write(config, BASE)  # robot3 and robot4 leave, the error goes away
        app.check_reload()
        assert set(app.robots) == {"robot1", "robot2"} and app.status()["errors"] == []
    finally:
        app.close()


def test_restart_puts_robots_back_where_they_were(files):
    config, status_file = files
    app = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        app.physics.command("robot1", 0.5, 0.0)
        app.run(sim_duration=2.0)  # writes a final status
    finally:
        app.close()
    status = json.loads(status_file.read_text())
    x = status["robots"]["robot1"]["pose"]["x"]
    assert x > 0.5  # it moved (pushing robot2 once it reached it)
    assert len(status["robots"]["robot1"]["trail"]) >= 3
    assert status["robots"]["robot1"]["scan_hits"]  # the wall and robot2 are in reach
    assert set(status) >= {"sim_time", "real_time_factor", "robots", "contacts", "errors", "obstacles"}

    again = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        rx, ry, _ = again.physics.robots["robot1"].pose()
        assert abs(rx - x) < 1e-3 and abs(ry - status["robots"]["robot1"]["pose"]["y"]) < 1e-3
        # Time goes on from where it stopped, not from 0.
        assert again.physics.sim_time == status["sim_time"] >= 2.0
        again.run(sim_duration=0.5)
        assert abs(json.loads(status_file.read_text())["sim_time"] - (status["sim_time"] + 0.5)) < 0.01
    finally:
        again.close()

    # After a crash (no final write) the clock resumes past anything it may have published since
    # its last write: forward, never back.
    crashed = json.loads(status_file.read_text())
    crashed["stopped"] = False
    status_file.write_text(json.dumps(crashed))
    resumed = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        assert (
            crashed["sim_time"] + 0.5
            <= resumed.physics.sim_time
            <= crashed["sim_time"] + 0.5 * max(1.0, crashed["real_time_factor"])
        )
    finally:
        resumed.close()

    # Another fleet's status file restores nothing.
    other = json.loads(status_file.read_text())
    other["fleet"] = "elsewhere"
    status_file.write_text(json.dumps(other))
    fresh = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        assert fresh.physics.sim_time == 0.0 and fresh.physics.robots["robot1"].pose()[0] == 0.0
    finally:
        fresh.close()


def test_invalid_world_at_start_raises(tmp_path):
    config = tmp_path / "world.yaml"
    config.write_text("robots:\n- {name: r1, pose: {x: nope}}\n")
    with pytest.raises(WorldError, match=r"world.yaml:2:\d+: .*'x' must be a number"):
        WorldApp(config)


def test_snapshot_draws_status_data(files, tmp_path):
    config, status_file = files
    app = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        app.physics.command("robot1", 0.6, 0.4)
        app.run(sim_duration=3.0)
        status = app.status()
    finally:
        app.close()
    png = draw_snapshot(status, tmp_path / "world.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_command_times_out_in_both_sim_and_wall_time(monkeypatch):
    """A command is dropped only when it is older than cmd_timeout in sim time AND in wall time."""
    import numpy as np

    from fleet.world import inputs as robot_inputs

    wall = [100.0]
    monkeypatch.setattr(robot_inputs.time, "monotonic", lambda: wall[0])
    inputs = robot_inputs.RobotInputs.empty(1, 2)
    inputs.commands[0] = (0.4, 0.1, 100.0, 10.0)  # robot 0: received at wall 100 s, sim 10 s
    timeouts = np.array([0.5, 0.5])

    def current(sim_time: float) -> list[float]:
        return inputs.live_commands(timeouts, sim_time).tolist()[0]

    assert current(10.2) == [0.4, 0.1]
    assert current(30.0) == [0.4, 0.1]  # far ahead in sim, but only just sent (fast world)
    wall[0] = 100.6
    assert current(10.3) == [0.4, 0.1]  # old in wall time, fresh in sim (slow world)
    assert current(10.6) == [0.0, 0.0]
    assert inputs.live_commands(timeouts, 10.0).tolist()[1] == [0.0, 0.0]  # robot 1: never commanded


def test_a_new_spawn_pose_moves_the_robot_there_at_a_reload_and_at_a_restart(files):
    config, status_file = files
    app = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        app.physics.command("robot1", 0.5, 0.0)
        app.run(sim_duration=0.5)
        robot1 = app.physics.robots["robot1"].pose()
        write(config, BASE.replace("{x: 1.0, y: 0.0, yaw: 1.57}", "{x: -1.5, y: -1.0, yaw: 0.0}"))
        app.check_reload()
        assert app.physics.robots["robot2"].pose() == pytest.approx((-1.5, -1.0, 0.0), abs=1e-6)
        assert app.physics.robots["robot1"].pose() == robot1  # the other one was not disturbed
        app.physics.command("robot1", 0.5, 0.0)
        app.run(sim_duration=0.5)  # writes a final status
    finally:
        app.close()
    status = json.loads(status_file.read_text())
    assert status["robots"]["robot2"]["spawn"] == {"x": -1.5, "y": -1.0, "yaw": 0.0}

    # Stopped, then started with robot1 given a new spawn pose: robot1 starts there, robot2 where it was.
    write(
        config,
        BASE.replace("{x: 1.0, y: 0.0, yaw: 1.57}", "{x: -1.5, y: -1.0, yaw: 0.0}").replace(
            "{x: 0.0, y: 0.0}", "{x: 0.5, y: -2.0}"
        ),
    )
    again = WorldApp(config, status_file, as_fast_as_possible=True)
    try:
        assert again.physics.robots["robot1"].pose() == pytest.approx((0.5, -2.0, 0.0), abs=1e-6)
        robot2 = status["robots"]["robot2"]["pose"]
        assert again.physics.robots["robot2"].pose() == pytest.approx(
            (robot2["x"], robot2["y"], robot2["yaw"]), abs=1e-3
        )
    finally:
        again.close()


@pytest.mark.parametrize(
    "status, resumed",
    [
        ({"sim_time": 10.0, "real_time_factor": 2.4, "stopped": True}, 10.0),  # a clean stop: where it stopped
        # A crash: two status periods (0.5 s of wall time) at the written speed, at least real time's
        # (docs/architecture.md, "A restarted world resumes from its status file").
        ({"sim_time": 10.0, "real_time_factor": 1.0, "stopped": False}, 10.5),
        ({"sim_time": 10.0, "real_time_factor": 0.3, "stopped": False}, 10.5),
        ({"sim_time": 10.0, "real_time_factor": 2.4, "stopped": False}, 11.2),
        ({"sim_time": 10.0, "real_time_factor": "fast", "stopped": False}, 10.5),
        (None, 0.0),
    ],
)
def test_a_restarted_world_resumes_its_clock_as_documented(status, resumed):
    assert resume_time(status) == pytest.approx(resumed)
