"""Every example fleet in fleets/ comes up and every one of its robots moves (its nodes get the
world's /clock and odometry, and the world gets their commands), on one agent process per
agent named in the spec."""

from __future__ import annotations

import pytest

from fleet.testing import running_fleet
from tests.e2e.e2e_helpers import FLEETS

pytestmark = pytest.mark.integration

EXAMPLES = sorted(FLEETS.glob("*.yaml"))


@pytest.mark.parametrize("spec", EXAMPLES, ids=[path.stem for path in EXAMPLES])
def test_every_robot_of_the_example_moves(spec, tmp_path):
    with running_fleet(spec, directory=tmp_path, timeout=240) as fleet:
        robots = [robot.name for robot in fleet.spec.robots]
        start = {robot: fleet.pose(robot) for robot in robots}

        def still():
            return [robot for robot in robots if fleet.pose(robot).distance_to(start[robot]) < 0.2]

        fleet.wait_for(
            lambda: not still(),
            sim_timeout=30,
            what="every robot to move 0.2 m",
            explain=lambda: f"not moved: {', '.join(still())}",
        )
        assert fleet.status().all_running
