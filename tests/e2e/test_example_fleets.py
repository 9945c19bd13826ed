"""Every example fleet in fleets/ comes up and every one of its robots moves (its nodes get the
world's /clock and odometry, and the world gets their commands), on one agent process per
agent named in the spec; robots that patrol go round their routes, and none drives into a wall
or an obstacle (a route through a wall leaves its robot stuck there, "running" all along)."""

from __future__ import annotations

import pytest

from fleet.testing import running_fleet
from tests.e2e.e2e_helpers import FLEETS, RouteProgress

pytestmark = pytest.mark.integration

EXAMPLES = sorted(FLEETS.glob("*.yaml"))


@pytest.mark.parametrize("spec", EXAMPLES, ids=[path.stem for path in EXAMPLES])
def test_every_robot_of_the_example_moves(spec, tmp_path):
    with running_fleet(spec, directory=tmp_path, timeout=240) as fleet:
        # From where the spec spawns them, and once is enough: under load a robot may have driven
        # its course before the fleet is up (safety_stop's scout stops at its crate 1.4 m out), and
        # a looping one passes its spawn point again.
        spawns = {robot.name: (robot.pose.x, robot.pose.y) for robot in fleet.spec.robots}
        moved: set[str] = set()

        def still():
            moved.update(robot for robot, spawn in spawns.items() if fleet.pose(robot).distance_to(spawn) >= 0.2)
            return sorted(set(spawns) - moved)

        fleet.wait_for(
            lambda: not still(),
            sim_timeout=30,
            what="every robot to move 0.2 m",
            explain=lambda: f"not moved: {', '.join(still())}",
        )
        assert fleet.status().all_running

        patrolling = [r for r in spawns if fleet.expansion.robot(r).parameters.effective()["controller"]["loop"]]
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
