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


# A node that prints the use_sim_time its parameter files give it.
PRINT_USE_SIM_TIME = """
import sys, rclpy
from rclpy.node import Node
rclpy.init(args=sys.argv)
node = Node("probe")
print(node.get_parameter("use_sim_time").value)
node.destroy_node()
rclpy.shutdown()
"""


@pytest.mark.integration
def test_a_value_the_launch_file_gives_inline_wins_over_the_parameter_file_as_explain_says(tmp_path, ros_env, capsys):
    """diff_drive gives every node use_sim_time inline after the robot's parameter file: a --set
    of it is written to the file, warned about, and shown overridden by --explain, and real rcl,
    reading the files of the command line the runner builds, gets the launch file's value."""
    from fleet.cli.plan_view import explain_data
    from fleet.expand import expand_fleet
    from fleet.runtime.launch_file import load_launch_file
    from fleet.spec.load import load_spec
    from tests.runtime.runtime_helpers import FakePrefix

    sets = ["--set", "robot1.controller.use_sim_time=false"]
    out = tmp_path / "out"
    assert run_fleet(["render", str(FLEETS / "two_robots.yaml"), "-o", str(out), *sets]) == 0
    warning = capsys.readouterr().err
    assert "--set robot1.controller.use_sim_time=false: controller.use_sim_time is not used" in warning
    assert "(robot1/robot1.launch.yaml:24:9: true), and that value wins" in warning
    assert "not a parameter of the template" not in warning  # the launch file knows the name

    expansion = expand_fleet(load_spec(FLEETS / "two_robots.yaml"), sets[1::2])
    explained = explain_data(expansion, "robot1.controller.use_sim_time")
    assert explained["value"] is True
    assert [(layer["layer"], layer["value"], layer["effective"]) for layer in explained["layers"]] == [
        ("--set", False, False),
        ("launch file", True, True),
    ]

    prefix = FakePrefix(tmp_path / "prefix")
    for exe in ("controller", "battery", "safety"):
        prefix.add(exe, "#!/bin/sh\nexec sleep 100\n", package="fleet_nodes")
    launch = out / "robot1" / "robot1.launch.yaml"
    plan = load_launch_file(launch, env=prefix.env(), params_dir=tmp_path / "params")
    (controller,) = [node for node in plan.nodes if node.name == "controller"]
    files = [controller.cmd[i + 1] for i, part in enumerate(controller.cmd) if part == "--params-file"]
    assert files[0] == str(out / "robot1" / "robot1.params.yaml") and len(files) == 2
    command = [
        sys.executable,
        "-c",
        PRINT_USE_SIM_TIME,
        "--ros-args",
        "-r",
        "__ns:=/robot1",
        "-r",
        "__node:=controller",
    ]
    for path in files:
        command += ["--params-file", path]
    result = subprocess.run(command, env=ros_env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip().splitlines()[-1] == "True"
    # Without the inline value, the file's would be read: the --set reached the file.
    files_only = command[: command.index("--params-file") + 2]
    result = subprocess.run(files_only, env=ros_env, capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and result.stdout.strip().splitlines()[-1] == "False", result.stderr
