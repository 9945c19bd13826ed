"""The embedded runner builds the command line launch_ros (Jazzy) builds.

DESIGN.md, "How launch_ros starts a node (Jazzy)", records what real `ros2 launch` produced for a
.launch.yaml with push_ros_namespace + node + param file + inline param + remap:

    ... -r __node:=controller -r __ns:=/robot1 --params-file robot1.params.yaml
        --params-file <tmpdir>/launch_params_xxxx -r cmd_vel:=cmd_vel_safe

and the general layout `<lib>/<pkg>/<exe> [arguments] --ros-args -r __node:=<name>
-r __ns:=/<ns> --params-file <file>... -r <from>:=<to>...` (launch_ros also puts the node's own
`ros_args` in a first `--ros-args` block after the arguments).
"""

from __future__ import annotations

import re
from pathlib import Path

import yaml

from fleet.runtime.isolation import plan_processes
from fleet.runtime.launch_file import load_launch_file

DESIGN_VERIFIED = (
    "-r __node:=controller -r __ns:=/robot1 --params-file robot1.params.yaml "
    "--params-file <tmpdir>/launch_params_xxxx -r cmd_vel:=cmd_vel_safe"
)

# The robot launch file of docs/architecture.md ("Rendered output"), as templates render it.
ROBOT_LAUNCH = """
launch:
- arg: {name: use_sim_time, default: 'true'}
- arg: {name: enable_safety, default: 'true'}
- arg: {name: log_level, default: info}
- group:
  - push_ros_namespace: {namespace: robot1}
  - let: {name: controller_cmd_vel, value: cmd_vel}
  - let: {name: controller_cmd_vel, value: cmd_vel_safe, if: $(var enable_safety)}
  - node:
      pkg: fleet_nodes
      exec: controller
      name: controller
      output: screen
      param:
      - {from: $(dirname)/robot1.params.yaml}
      - {name: use_sim_time, value: $(var use_sim_time)}
      remap:
      - {from: cmd_vel, to: $(var controller_cmd_vel)}
  - node:
      pkg: fleet_nodes
      exec: battery
      name: battery
      ros_args: --log-level $(var log_level)
      param:
      - {from: $(dirname)/robot1.params.yaml}
  - node:
      pkg: fleet_nodes
      exec: safety
      name: safety
      if: $(var enable_safety)
      remap:
      - {from: cmd_vel_in, to: cmd_vel_safe}
      - {from: cmd_vel_out, to: cmd_vel}
"""


def _normalise(cmd: list[str], launch_dir: Path) -> str:
    """Replace what differs per run (directories, temp names) with DESIGN.md's placeholders."""
    text = " ".join(cmd)
    text = re.sub(r"\S*/launch_params_\w+", "<tmpdir>/launch_params_xxxx", text)
    return text.replace(f"{launch_dir}/", "")


def _robot_plan(prefix, tmp_path, **launch_args):
    for exe in ("controller", "battery", "safety", "composite"):
        prefix.add(exe, "#!/bin/sh\nexec sleep 100\n", package="fleet_nodes")
    launch_dir = tmp_path / "out" / "robot1"
    launch_dir.mkdir(parents=True)
    (launch_dir / "robot1.params.yaml").write_text("/robot1/controller: {ros__parameters: {}}\n")
    path = launch_dir / "robot1.launch.yaml"
    path.write_text(ROBOT_LAUNCH)
    return load_launch_file(path, launch_args, env=prefix.env(), params_dir=tmp_path / "params")


def test_controller_matches_design_md(prefix, tmp_path):
    plan = _robot_plan(prefix, tmp_path)
    controller = plan.nodes[0]
    exe = str(prefix.root / "lib" / "fleet_nodes" / "controller")
    assert controller.cmd[0] == exe
    assert _normalise(controller.cmd, tmp_path / "out" / "robot1") == f"{exe} --ros-args {DESIGN_VERIFIED}"
    inline = yaml.safe_load(Path(controller.cmd[controller.cmd.index("-r", 6) - 1]).read_text())
    assert inline == {"/robot1/controller": {"ros__parameters": {"use_sim_time": True}}}


def test_general_layout_of_every_node(prefix, tmp_path):
    plan = _robot_plan(prefix, tmp_path)
    lib = prefix.root / "lib" / "fleet_nodes"
    layouts = [_normalise(node.cmd, tmp_path / "out" / "robot1") for node in plan.nodes]
    assert layouts == [
        f"{lib}/controller --ros-args {DESIGN_VERIFIED}",
        f"{lib}/battery --ros-args --log-level info --ros-args -r __node:=battery "
        "-r __ns:=/robot1 --params-file robot1.params.yaml",
        f"{lib}/safety --ros-args -r __node:=safety -r __ns:=/robot1 "
        "-r cmd_vel_in:=cmd_vel_safe -r cmd_vel_out:=cmd_vel",
    ]


def test_condition_removes_safety_and_changes_remap(prefix, tmp_path):
    plan = _robot_plan(prefix, tmp_path, enable_safety="false")
    assert [node.name for node in plan.nodes] == ["controller", "battery"]
    assert plan.nodes[0].cmd[-2:] == ["-r", "cmd_vel:=cmd_vel"]


def test_robot_isolation_composite_argv(prefix, tmp_path):
    """The composite gets, per node, `--fleet-node EXE` and exactly the node's own arguments."""
    plan = _robot_plan(prefix, tmp_path)
    (composite,) = plan_processes(plan.nodes, "robot")
    expected = [str(prefix.root / "lib" / "fleet_nodes" / "composite")]
    for node in plan.nodes:
        expected += ["--fleet-node", node.executable, *node.cmd[1:]]
    assert composite.cmd == expected
    assert composite.name == "composite-1"
    assert [node.name for node in composite.nodes] == ["controller", "battery", "safety"]
    assert composite.echo is True  # the controller has output: screen


def test_robot_isolation_keeps_other_nodes_alone(prefix, tmp_path):
    prefix.add("world", "#!/bin/sh\nexec sleep 100\n", package="fleet_nodes")
    prefix.add("talker", "#!/bin/sh\nexec sleep 100\n")
    plan = _robot_plan(prefix, tmp_path)
    extra = tmp_path / "more.launch.yaml"
    extra.write_text(
        "launch:\n"
        "- node: {pkg: demo, exec: talker, name: t}\n"
        "- node: {pkg: fleet_nodes, exec: controller, name: c1, namespace: r1}\n"
        "- node: {pkg: fleet_nodes, exec: world, name: world}\n"
        "- node: {pkg: fleet_nodes, exec: battery, name: b1, namespace: r1}\n"
        "- node: {pkg: fleet_nodes, exec: safety, name: s1, namespace: r1, args: --plain}\n"
    )
    plan = load_launch_file(extra, env=prefix.env(), params_dir=tmp_path / "params")
    specs = plan_processes(plan.nodes, "robot")
    # Process names count with one counter for the whole launch, as launch does (issue 11).
    assert [spec.name for spec in specs] == ["talker-1", "composite-1", "world-3", "safety-5"]
    assert [node.name for node in specs[1].nodes] == ["c1", "b1"]
    assert [spec.name for spec in plan_processes(plan.nodes, "process")] == [
        "talker-1",
        "controller-2",
        "world-3",
        "battery-4",
        "safety-5",
    ]
