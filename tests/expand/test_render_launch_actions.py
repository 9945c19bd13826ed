"""Templates may use every action the agents' runner runs (the one reader decides both), and
render refuses, in one line, what the runner would refuse."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

import pytest

from fleet.errors import TemplateError
from fleet.expand import expand_fleet
from fleet.runtime.launch_file import load_launch_file
from fleet.spec import parse_spec
from tests.runtime.runtime_helpers import FakePrefix

TUTORIAL_TEMPLATE = """
launch:
- arg: {name: mode, default: slow, description: How fast, choice: [{value: slow}, {value: fast}]}
- log: {message: {{ robot.name }}}
- group:
    scoped: true
    children:
    - push_ros_namespace: {namespace: {{ robot.namespace }}}
    - set_env: {name: FLEET_ROBOT, value: {{ robot.name }}}
    - unset_env: {name: FLEET_NOT_FOR_NODES}
    - set_parameter: {name: use_sim_time, value: 'true'}
    - set_remap: {from: cmd_vel, to: cmd_vel_safe}
    - node:
        pkg: demo
        exec: talker
        name: controller
        env: [{name: ONLY_HERE, value: '1'}]
        param: [{from: {{ params_file }}}]
    - timer:
        period: 0.5
        children:
        - executable: {cmd: /bin/true, name: late}
- include:
    file: $(env EXTRA_LAUNCH_DIR)/extra.launch.yaml
    arg: [{name: robot, value: {{ robot.name }}}]
"""


def write_spec(tmp_path: Path, template: str) -> Path:
    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "tutorial.launch.yaml.j2").write_text(textwrap.dedent(template).lstrip())
    (templates / "tutorial.params.yaml").write_text("controller: {}\n")
    spec = tmp_path / "fleet.yaml"
    spec.write_text("fleet: t\ntemplates: templates\nrobots:\n- {name: r1, template: tutorial}\n")
    return spec


def test_a_template_using_the_tutorials_actions_renders_and_runs(tmp_path):
    spec_path = write_spec(tmp_path, TUTORIAL_TEMPLATE)
    plan = expand_fleet(parse_spec(spec_path.read_text(), str(spec_path)))
    (robot,) = [bundle for bundle in plan.bundles if bundle.name == "r1"]
    assert [node.fqn for node in plan.robots[0].outline.nodes] == ["/r1/controller"]
    out = tmp_path / "out"
    out.mkdir()
    for name, text in robot.files.items():
        (out / name).write_text(text)
    (out / "extra.launch.yaml").write_text(
        "launch:\n- arg: {name: robot}\n- node: {pkg: demo, exec: talker, name: x}\n"
    )
    prefix = FakePrefix(tmp_path / "prefix")
    prefix.add("talker", "#!/bin/sh\nexec sleep 100\n")
    launch = next(out / name for name in robot.files if name.endswith(".launch.yaml"))
    # A file outside the bundle (an agent's unit directory holds only the bundle's files).
    env = {**prefix.env(), "EXTRA_LAUNCH_DIR": str(out)}
    ran = load_launch_file(launch, env=env, params_dir=tmp_path / "params")
    assert [node.process_name for node in ran.nodes] == ["talker-1", "talker-2", "late-3"]
    assert ran.logs == ["r1"]
    python = next(text for name, text in robot.files.items() if name.endswith(".launch.py"))
    compile(python, "robot.launch.py", "exec")  # the Python twin is Python
    for action in ("TimerAction(", "IncludeLaunchDescription(", "SetRemap(", "ExecuteProcess(", "LogInfo("):
        assert action in python


@pytest.mark.parametrize(
    ("action", "problem"),
    [
        ("- shutdown: {}", "action 'shutdown' needs the ros2 backend"),
        ("- node: {pkg: demo, exec: talker, name: n, launch-prefix: gdb}", "attribute 'launch-prefix' of 'node' needs"),
        ("- teleport: {}", "unknown action 'teleport'"),
        ("- nod: {pkg: demo, exec: talker}", "unknown action 'nod' (did you mean 'node'?)"),
        ("- node: {pkg: demo, exec: talker, name: n, respawn: true}", "must be a string"),
    ],
)
def test_render_refuses_what_the_runner_refuses(tmp_path, action, problem):
    spec_path = write_spec(tmp_path, f"launch:\n{action}\n")
    with pytest.raises(TemplateError) as caught:
        expand_fleet(parse_spec(spec_path.read_text(), str(spec_path)))
    line = caught.value.line()
    assert line.startswith("fleet: error: ") and "tutorial.launch.yaml.j2" in line
    assert "line 2, column " in line and problem in line


def test_the_python_twin_expresses_every_substitution_the_reader_accepts():
    from fleet.expand.python_launch import python_launch_source

    node = {
        "pkg": "p",
        "exec": "e",
        "name": "n",
        "if": "$(and $(var a) $(not $(equals $(var b) x)))",
        "args": "$(find-pkg-prefix p)/x $(filename) $(exec-in-pkg e p) $(env A $(var d))",
    }
    source = python_launch_source({"launch": [{"node": node}]}, "c")
    compile(source, "robot.launch.py", "exec")
    assert "condition=IfCondition([AndSubstitution([LaunchConfiguration('a')], [NotSubstitution(" in source
    for name in ("FindPackagePrefix", "ThisLaunchFile", "ExecutableInPackage", "EqualsSubstitution"):
        assert f"import {name}\n" in source


@pytest.mark.parametrize(
    "args",
    ['--robot "t1" --x 0.0', "'a b' c'd'e  \"\"", "x$(var v) y", "$(var v)  $(var v)", "   ", '--name="t 1" -v'],
)
def test_the_python_twin_passes_the_arguments_the_runner_passes(tmp_path, args):
    """One splitter: quotes in `args` mean the same to the runner and in the .launch.py."""
    from fleet.expand.python_launch import python_launch_source

    prefix = FakePrefix(tmp_path / "prefix")
    prefix.add("talker", "#!/bin/sh\n")
    launch = tmp_path / "r.launch.yaml"
    node_yaml = f"- node:\n    pkg: demo\n    exec: talker\n    args: {json.dumps(args)}\n"
    launch.write_text("launch:\n- let: {name: v, value: V}\n" + node_yaml)
    (node,) = load_launch_file(launch, env=prefix.env()).nodes
    ran = node.cmd[1 : node.cmd.index("--ros-args")]
    source = python_launch_source({"launch": [{"node": {"pkg": "demo", "exec": "talker", "args": args}}]}, "c")
    written = source.split("arguments=", 1)[1].split("\n", 1)[0].rstrip(",")
    passed = eval(written, {"LaunchConfiguration": lambda name: "V"})  # the twin's substitutions, resolved
    assert ["".join(argument) if isinstance(argument, list) else argument for argument in passed] == ran
