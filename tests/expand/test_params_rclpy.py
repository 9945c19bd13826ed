"""The generated per-namespace parameter files, read by real rclpy (rcl's YAML parser)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from tests.checkout import FLEETS, run_fleet

# A node that accepts whatever its parameter files give it and prints what it got.
PRINT_PARAMETERS = """
import json, sys, rclpy
from rclpy.node import Node
rclpy.init(args=sys.argv)
node = Node("probe", automatically_declare_parameters_from_overrides=True)
values = {name: p.value for name, p in node._parameters.items()
          if name not in ("use_sim_time", "start_type_description_service")}
print(json.dumps({"fqn": node.get_fully_qualified_name(), "parameters": values}))
node.destroy_node()
rclpy.shutdown()
"""


def probe(ros_env, namespace: str, name: str, params_files: list) -> dict:
    command = [
        sys.executable,
        "-c",
        PRINT_PARAMETERS,
        "--ros-args",
        "-r",
        f"__ns:={namespace}",
        "-r",
        f"__node:={name}",
    ]
    for path in params_files:
        command += ["--params-file", str(path)]
    result = subprocess.run(command, env=ros_env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    return json.loads(result.stdout.strip().splitlines()[-1])


@pytest.mark.integration
def test_each_robot_node_sees_its_own_section(tmp_path, ros_env):
    out = tmp_path / "out"
    assert (
        run_fleet(
            ["render", str(FLEETS / "two_robots.yaml"), "-o", str(out), "--set", "robot1.safety.safety_distance=0.3"]
        )
        == 0
    )
    robot1 = out / "robot1" / "robot1.params.yaml"
    robot2 = out / "robot2" / "robot2.params.yaml"
    # Both files on each command line, the other robot's last: only the fully-qualified section
    # of the node's own name may apply (no wildcard precedence games).
    got1 = probe(ros_env, "/robot1", "controller", [robot1, robot2])
    got2 = probe(ros_env, "/robot2", "controller", [robot2, robot1])
    assert got1["fqn"] == "/robot1/controller" and got2["fqn"] == "/robot2/controller"
    assert got1["parameters"]["max_speed"] == 0.4
    assert got2["parameters"]["max_speed"] == 0.8
    assert got1["parameters"]["waypoints"] == [1.0, 0.0, 1.0, 2.0, -1.0, 2.0, -1.0, 0.0]
    assert got2["parameters"]["waypoints"][:2] == [0.0, 2.0]
    safety1 = probe(ros_env, "/robot1", "safety", [robot1, robot2])
    safety2 = probe(ros_env, "/robot2", "safety", [robot2, robot1])
    assert safety1["parameters"] == {"safety_distance": 0.3, "scan_half_angle": 0.6, "scan_timeout": 1.0}
    assert safety2["parameters"]["safety_distance"] == 0.4
