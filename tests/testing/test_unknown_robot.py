"""A misspelt robot name fails at once, naming the fleet's robots, wherever a robot is named:
`assert not fleet.contacts("alhpa")` must not pass by looking at nobody.  (No fleet runs here:
the handle is only constructed, and the world's status is a stand-in.)"""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from fleet.testing import FleetHandle, NotSimulated, UnknownRobot
from tests.e2e.e2e_helpers import TWO_ROBOTS

WORLD_STATUS = {
    "sim_time": 1.0,
    "robots": {"robot1": {"pose": {"x": 1.0, "y": 0.0, "yaw": 0.0}, "velocity": {"linear": 0.2, "angular": 0.0}}},
    "contacts": {"count": 1, "last": [{"sim_time": 0.5, "a": "robot1", "b": "crate", "kind": "box"}]},
}


@pytest.fixture
def fleet(tmp_path, monkeypatch) -> Iterator[FleetHandle]:
    handle = FleetHandle(TWO_ROBOTS, tmp_path / "fleet")
    monkeypatch.setattr(handle, "world", lambda: WORLD_STATUS)
    try:
        yield handle
    finally:
        handle.close()


@pytest.mark.parametrize(
    "use",
    [
        lambda fleet: fleet.contacts("robotX"),
        lambda fleet: fleet.pose("robotX"),
        lambda fleet: fleet.velocity("robotX"),
        lambda fleet: fleet.battery("robotX"),
        lambda fleet: fleet.topic("robotX", "odom"),
        lambda fleet: fleet.topic("robotX", "/clock"),
        lambda fleet: fleet.robot_status("robotX"),
        lambda fleet: fleet.node_pid("robotX", "controller"),
        lambda fleet: fleet.logs("robotX"),
        lambda fleet: fleet.subscribe("robotX", "odom"),
        lambda fleet: fleet.get_param("robotX", "controller", "max_speed"),
    ],
    ids=[
        "contacts",
        "pose",
        "velocity",
        "battery",
        "topic",
        "absolute topic",
        "robot_status",
        "node_pid",
        "logs",
        "subscribe",
        "get_param",
    ],
)
def test_an_unknown_robot_is_an_error_naming_the_fleets_robots(fleet, use):
    with pytest.raises(UnknownRobot, match=r"^fleet two_robots has no robot 'robotX'; it has: robot1, robot2\b"):
        use(fleet)


def test_known_robots_still_answer(fleet):
    assert fleet.pose("robot1").x == 1.0
    assert fleet.contacts("robot1") and not fleet.contacts("robot2")
    assert fleet.topic("robot2", "odom") == "/robot2/odom"


MIXED = """\
fleet: mixed
world: {}
robots:
- {name: sim1}
- {name: bench, simulated: false, launch_args: {use_sim_time: false}}
"""


@pytest.mark.parametrize(
    "use",
    [
        lambda fleet: fleet.pose("bench"),
        lambda fleet: fleet.velocity("bench"),
        lambda fleet: fleet.battery("bench"),
        lambda fleet: fleet.contacts("bench"),
        lambda fleet: fleet.wait_for(lambda: fleet.pose("bench").x > 1.0, timeout=5),
    ],
    ids=["pose", "velocity", "battery", "contacts", "wait_for"],
)
def test_a_real_robot_has_nothing_in_the_world_and_says_so(tmp_path, monkeypatch, use):
    """The world does not host a real robot (`simulated: false`): asking it for one's pose was a
    bare KeyError('bench'), its contacts an empty list (so `assert not fleet.contacts("bench")`
    passed by looking at nobody), and a wait on its pose ran to its timeout."""
    spec = tmp_path / "mixed.yaml"
    spec.write_text(MIXED)
    handle = FleetHandle(spec, tmp_path / "fleet")
    robot1 = {"pose": {"x": 1.0, "y": 0.0, "yaw": 0.0}, "velocity": {"linear": 0.2, "angular": 0.0}}
    monkeypatch.setattr(handle, "world", lambda: {**WORLD_STATUS, "robots": {"sim1": robot1}})
    try:
        assert handle.pose("sim1").x == 1.0
        with pytest.raises(NotSimulated, match=r"^fleet mixed: the world does not host robot 'bench' \(it is real"):
            use(handle)
    finally:
        handle.close()
