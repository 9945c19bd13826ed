"""The generated per-namespace parameter files, read by real rclpy (rcl's YAML parser)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

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


# A process like a navigation server's: its own node, named by the global arguments launch gives
# the process (-r __node:=, -r __ns:=, --params-file), and nodes it creates inside itself under
# names of their own (node-local arguments, as a server creating a costmap node gives them).
# Prints every node's full name and each parameter's ROS type and value.
PRINT_HOSTED_PARAMETERS = """
import json, os, sys, rclpy
from rclpy.node import Node
rclpy.init(args=sys.argv)
nodes = [Node("host", automatically_declare_parameters_from_overrides=True)]
for hosted in json.loads(os.environ["HOSTED_NODES"]):
    namespace, name = hosted.rsplit("/", 1)
    arguments = ["--ros-args", "-r", f"__ns:={namespace}", "-r", f"{name}:__node:={name}"]
    nodes.append(Node(name, cli_args=arguments, automatically_declare_parameters_from_overrides=True))
report = {}
for node in nodes:
    report[node.get_fully_qualified_name()] = {
        name: [p.type_.name, list(p.value) if p.type_.name.endswith("_ARRAY") else p.value]
        for name, p in node._parameters.items()
        if name not in ("use_sim_time", "start_type_description_service")
    }
print(json.dumps(report))
for node in nodes:
    node.destroy_node()
rclpy.shutdown()
"""

NAVLIKE = Path(__file__).parent / "data" / "navlike"


def ros_type(value) -> str:
    if isinstance(value, list):
        return ros_type(value[0]) + "_ARRAY"
    return {bool: "BOOL", int: "INTEGER", float: "DOUBLE", str: "STRING"}[type(value)]


@pytest.mark.integration
def test_rcl_reads_every_value_fleet_wrote_with_its_type(tmp_path, ros_env):
    """Every parameter of a navigation-like fleet (plugin groups, hosted costmap nodes, `1e-3`
    covariances, strings like "1_000" and "y"), as real rcl reads the written files in the
    processes launch would start: exactly the typed values fleet meant, which --explain reports."""
    from fleet.cli.plan_view import explain_data
    from fleet.expand import expand_fleet
    from fleet.spec.load import load_spec

    spec = tmp_path / "navlike" / "fleet.yaml"
    shutil.copytree(NAVLIKE, spec.parent)
    extra = '      localizer: {odom0: "y", imu0: "1_000", map_frame: "inf", transform_timeout: 1e-3}\n'
    spec.write_text(spec.read_text().replace("      controller_server:\n", extra + "      controller_server:\n", 1))
    sets = ["--set", "robot2.local_costmap/local_costmap.resolution=25e-3", "--set", "robot2.localizer.debug=Y"]
    out = tmp_path / "out"
    assert run_fleet(["render", str(spec), "-o", str(out), *sets]) == 0
    expansion = expand_fleet(load_spec(spec), sets[1::2])
    plan = expansion.robot("robot2")
    assert plan is not None
    params_file = out / "robot2" / "robot2.params.yaml"
    env = dict(ros_env, HOSTED_NODES=json.dumps(["/robot2/local_costmap/local_costmap"]))
    command = [sys.executable, "-c", PRINT_HOSTED_PARAMETERS, "--ros-args", "-r", "__ns:=/robot2"]
    got = {}
    for host in ("localizer", "controller_server"):
        argv = [*command, "-r", f"__node:={host}", "--params-file", str(params_file)]
        result = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=60)
        assert result.returncode == 0, result.stderr
        got.update(json.loads(result.stdout.strip().splitlines()[-1]))
    assert set(got) == {
        "/robot2/localizer",
        "/robot2/controller_server",
        "/robot2/local_costmap/local_costmap",
    }
    counted = 0
    for node in ("localizer", "controller_server", "local_costmap/local_costmap"):
        expected = plan.parameters.effective_of(node)
        read = got[f"/robot2/{node}"]
        assert set(read) == set(expected)
        for name, value in expected.items():
            assert read[name] == [ros_type(value), value], name
            assert explain_data(expansion, f"robot2.{node}.{name}")["value"] == value
            counted += 1
    assert counted > 100
    localizer = got["/robot2/localizer"]
    assert localizer["odom0"] == ["STRING", "y"] and localizer["imu0"] == ["STRING", "1_000"]
    assert localizer["map_frame"] == ["STRING", "inf"] and localizer["transform_timeout"] == ["DOUBLE", 0.001]
    assert localizer["firmware_build"] == ["STRING", "1_000"] and localizer["max_lag"] == ["DOUBLE", 1e-10]
    assert localizer["debug"] == ["BOOL", True]
    assert localizer["process_noise_covariance"][0] == "DOUBLE_ARRAY"
    assert got["/robot2/local_costmap/local_costmap"]["resolution"] == ["DOUBLE", 0.025]
