"""A new user's 30-robot fleet on sim time, every setting at its default (`isolation: agent`,
hosts of 25 robots): it comes up and every robot drives (its data flows both ways)."""

from __future__ import annotations

import pytest
import yaml

from fleet.testing import running_fleet
from tests.checkout import REPO
from tests.e2e.e2e_helpers import wait_every_robot_left_its_spawn

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
        robots = [bundle for bundle in fleet.expansion.bundles if bundle.kind == "robot"]
        assert {bundle.options.get("isolation") for bundle in robots} == {"agent"}  # the default
        wait_every_robot_left_its_spawn(fleet)
        assert fleet.status().all_running
