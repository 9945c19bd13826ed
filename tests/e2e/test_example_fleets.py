"""Every example fleet in fleets/ comes up and every one of its robots moves (its nodes get the
world's /clock and odometry, and the world gets their commands), on one agent process per
agent named in the spec; robots that patrol go round their routes, and none drives into a wall
or an obstacle (a route through a wall leaves its robot stuck there, "running" all along)."""

from __future__ import annotations

import pytest

from fleet.testing import running_fleet
from tests.e2e.e2e_helpers import FLEETS, RouteProgress, wait_every_robot_left_its_spawn

pytestmark = pytest.mark.integration

EXAMPLES = sorted(FLEETS.glob("*.yaml"))


@pytest.mark.parametrize("spec", EXAMPLES, ids=[path.stem for path in EXAMPLES])
def test_every_robot_of_the_example_moves(spec, tmp_path):
    with running_fleet(spec, directory=tmp_path, timeout=240) as fleet:
        wait_every_robot_left_its_spawn(fleet)
        assert fleet.status().all_running

        robots = [robot.name for robot in fleet.spec.robots]
        patrolling = [r for r in robots if fleet.expansion.robot(r).parameters.effective()["controller"]["loop"]]
        routes = {robot: RouteProgress(fleet, robot) for robot in patrolling}

        def stuck():
            return sorted(robot for robot, route in routes.items() if route.update() < 2)

        fleet.wait_for(
            lambda: not stuck(),
            sim_timeout=40,
            what="every patrolling robot to reach two waypoints in a row",
            explain=lambda: f"not there: {', '.join(stuck())}",
        )
        assert not [c for c in fleet.contacts() if c["kind"] == "robot-obstacle"]
