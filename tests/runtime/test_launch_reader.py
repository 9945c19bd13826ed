"""The one launch reader: located refusals (FILE:LINE:COL), XML beside YAML, includes (cycles,
missing files, required arguments), choices, the ros2-backend pointers."""

from __future__ import annotations

import pytest

from fleet.errors import LaunchFileError
from fleet.launchfile import read_launch_file
from fleet.runtime.launch_file import load_launch_file


@pytest.fixture
def demo(prefix):
    prefix.add("talker", "#!/bin/sh\nexec sleep 100\n")
    return prefix


def refusal(path, demo, **launch_args) -> str:
    with pytest.raises(LaunchFileError) as caught:
        load_launch_file(path, launch_args, env=demo.env())
    return caught.value.line()


def test_refusals_name_file_line_and_column(write_launch, demo):
    path = write_launch("launch:\n- node: {pkg: demo, exec: talker}\n- group:\n  - ros_timer: {period: 1.0}\n")
    assert (
        refusal(path, demo) == f"fleet: error: {path}:4:5: action 'ros_timer' needs the ros2 backend (--backend ros2)"
    )
    path = write_launch("launch:\n- node: {pkg: demo, exec: talker, args: $(eval 1+1)}\n")
    assert f"{path}:2:35: substitution '$(eval)' is not run by the embedded runner" in refusal(path, demo)


def test_include_with_arguments_and_find_pkg_share(write_launch, demo):
    share = demo.root / "share" / "demo"
    share.mkdir(parents=True)
    (share / "robot.launch.yaml").write_text(
        "launch:\n- arg: {name: robot}\n- node: {pkg: demo, exec: talker, name: t, namespace: $(var robot)}\n"
    )
    path = write_launch(
        "launch:\n- include:\n    file: $(find-pkg-share demo)/robot.launch.yaml\n    arg: [{name: robot, value: r1}]\n"
    )
    plan = load_launch_file(path, env=demo.env())
    assert [node.fqn for node in plan.nodes] == ["/r1/t"]


def test_include_cycle_and_missing_file_are_located(write_launch, demo, tmp_path):
    write_launch("launch:\n- include: {file: $(dirname)/a.launch.yaml}\n", "b.launch.yaml")
    first = write_launch(
        "launch:\n- node: {pkg: demo, exec: talker}\n- include: {file: $(dirname)/b.launch.yaml}\n", "a.launch.yaml"
    )
    line = refusal(first, demo)
    assert line.startswith(f"fleet: error: {tmp_path / 'b.launch.yaml'}:2:3: include cycle: ")
    assert "a.launch.yaml -> b.launch.yaml -> a.launch.yaml" in line
    missing = write_launch("launch:\n- include: {file: $(dirname)/gone.launch.yaml}\n")
    assert refusal(missing, demo).startswith(f"fleet: error: {missing}:2:3: included launch file ")


def test_include_needs_the_required_arguments(write_launch, demo):
    write_launch("launch:\n- arg: {name: robot}\n", "needs.launch.yaml")
    path = write_launch("launch:\n- let: {name: robot, value: r1}\n- include: {file: $(dirname)/needs.launch.yaml}\n")
    # launch checks the include's own arguments, not the configurations already set.
    assert "needs argument 'robot'" in refusal(path, demo)


def test_argument_choices(write_launch, demo):
    path = write_launch(
        "launch:\n- arg:\n    name: mode\n    default: slow\n    choice: [{value: slow}, {value: fast}]\n"
    )
    assert load_launch_file(path, {"mode": "fast"}, env=demo.env()).arguments == {"mode": "fast"}
    line = refusal(path, demo, mode="bogus")
    assert line == f"fleet: error: {path}:2:3: argument 'mode' is 'bogus', not one of its choices (slow, fast)"
    bad_default = write_launch("launch:\n- arg: {name: m, default: x, choice: [{value: a}]}\n")
    assert "default 'x' of argument 'm' is not one of its choices" in refusal(bad_default, demo)


def test_xml_and_yaml_give_one_description(write_launch, demo):
    yaml_path = write_launch(
        "launch:\n- arg: {name: r, default: r1}\n- group:\n  - push_ros_namespace: {namespace: $(var r)}\n"
        "  - node: {pkg: demo, exec: talker, name: t, args: a b, remap: [{from: x, to: y}]}\n"
    )
    xml_path = write_launch(
        '<launch>\n  <arg name="r" default="r1"/>\n  <group>\n    <push-ros-namespace namespace="$(var r)"/>\n'
        '    <node pkg="demo" exec="talker" name="t" args="a b">\n      <remap from="x" to="y"/>\n    </node>\n'
        "  </group>\n</launch>\n",
        "test.launch.xml",
    )
    from_yaml = load_launch_file(yaml_path, env=demo.env())
    from_xml = load_launch_file(xml_path, env=demo.env())
    assert from_yaml.nodes[0].cmd == from_xml.nodes[0].cmd
    assert from_yaml.arguments == from_xml.arguments == {"r": "r1"}


def test_xml_refusals_are_located(write_launch, demo):
    path = write_launch('<launch>\n  <node pkg="demo" exec="talker" launch-prefix="gdb"/>\n</launch>\n', "x.launch.xml")
    assert (
        refusal(path, demo)
        == f"fleet: error: {path}:2:3: attribute 'launch-prefix' of 'node' needs the ros2 backend (--backend ros2)"
    )
    broken = write_launch("<launch>\n  <node pkg='demo'\n</launch>\n", "broken.launch.xml")
    assert refusal(broken, demo).startswith(f"fleet: error: {broken}:3:")


def test_xml_nested_past_the_yaml_bound_is_refused_at_the_element(write_launch, demo):
    """As a YAML launch file is (64 deep): reading 5,000 nested groups ended in a RecursionError."""
    deep = write_launch("<launch>\n" + "<group>" * 5000 + "</group>" * 5000 + "\n</launch>\n", "deep.launch.xml")
    assert refusal(deep, demo) == (
        f"fleet: error: {deep}:2:442: more than 64 nested elements: too deep for a fleet input"
    )


def test_python_launch_file_points_to_ros2_launch(demo, tmp_path):
    path = tmp_path / "robot.launch.py"
    path.write_text("def generate_launch_description(): ...\n")
    with pytest.raises(LaunchFileError, match=r"needs the ros2 backend \(--backend ros2\)"):
        read_launch_file(path)


def test_timer_executable_env_and_log(write_launch, demo):
    path = write_launch(
        "launch:\n- set_env: {name: A, value: '1'}\n- unset_env: {name: HOME}\n- log: {message: hi $(var x)}\n"
        "- timer: {period: 0.5, children: [{node: {pkg: demo, exec: talker, env: [{name: B, value: '2'}]}}]}\n"
        "- executable: {cmd: /bin/echo one 'two three', name: shout}\n"
    )
    plan = load_launch_file(path, {"x": "there"}, env=demo.env())
    echo, talker = plan.nodes
    assert plan.logs == ["hi there"]
    assert (echo.cmd, echo.process_name, echo.delay) == (["/bin/echo", "one", "two three"], "shout-1", 0.0)
    assert (talker.env, talker.env_unset, talker.delay, talker.process_name) == (
        {"A": "1", "B": "2"},
        ("HOME",),
        0.5,
        "talker-2",
    )
