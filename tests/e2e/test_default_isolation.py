"""A new user's 30-robot fleet on sim time, every setting at its default (`isolation: agent`,
hosts of 25 robots): it comes up and every robot drives (its data flows both ways)."""

from __future__ import annotations

import pytest
import yaml

from fleet.testing import running_fleet
from tests.checkout import REPO

pytestmark = pytest.mark.integration

ROBOTS = 30


def test_thirty_robots_on_the_default_isolation_all_drive(tmp_path):
    spec = {
        "fleet": "thirty",
        "templates": str(REPO / "templates"),
        "ros": {"use_sim_time": True},
        "world": {"physics_rate": 240},
        "defaults": {
            "template": "diff_drive",
            "parameters": {"controller": {"waypoints": [1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]}},
        },
        "robots": [
            {"name": f"bot{index:02d}", "pose": {"x": (index % 10) * 2.0, "y": (index // 10) * 3.0}}
            for index in range(ROBOTS)
        ],
    }
    path = tmp_path / "thirty.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    with running_fleet(path, directory=tmp_path / "run", timeout=180) as fleet:
        assert {row.get("isolation") for row in [b.options for b in fleet.expansion.bundles if b.kind == "robot"]} == {
            "agent"
        }
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
