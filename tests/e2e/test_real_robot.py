"""A fleet of simulated robots and a real one (`simulated: false`): the world hosts only the
simulated, and the real robot is `running` once its nodes run and are in the ROS graph, not
held `degraded` as "not in the world" (which kept `fleet deploy` from ever saying the fleet is up)."""

from __future__ import annotations

import pytest
import yaml

from fleet.testing import running_fleet
from tests.checkout import REPO
from tests.e2e.e2e_helpers import wait_every_robot_left_its_spawn

pytestmark = pytest.mark.integration


def test_a_real_robot_runs_beside_simulated_ones(tmp_path):
    spec = {
        "fleet": "mixed",
        "templates": str(REPO / "templates"),
        "ros": {"use_sim_time": True},
        "world": {},
        "defaults": {
            "template": "diff_drive",
            "isolation": "process",
            "parameters": {"controller": {"waypoints": [1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 0.0]}},
        },
        "robots": [
            {"name": "sim1"},
            # On a computer of its own in real life, on its own clock.
            {"name": "bench", "simulated": False, "launch_args": {"use_sim_time": False}},
        ],
    }
    path = tmp_path / "mixed.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    # running_fleet's deploy waits until every robot runs, the real one included.
    with running_fleet(path, directory=tmp_path / "run", timeout=120) as fleet:
        assert fleet.expansion.warnings == []
        rows = {row.name: row for row in fleet.status().robots}
        assert rows["bench"].state == "running" and not rows["bench"].simulated, rows["bench"]
        assert all(node["in_graph"] for node in rows["bench"].nodes if node.get("ros")), rows["bench"].nodes
        assert rows["sim1"].simulated and rows["sim1"].state == "running"
        world = fleet.world()
        assert world is not None and sorted(world["robots"]) == ["sim1"]
        wait_every_robot_left_its_spawn(fleet)
