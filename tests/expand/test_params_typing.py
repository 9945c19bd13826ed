"""Parameter values typed as rcl types them, wherever fleet reads them; parameters of nodes a
template's processes host; --set on a group; warnings about unknown names.

tests/expand/data/navlike is a navigation stack in miniature written for these tests: servers
hosting costmap nodes, plugin groups, covariance lists spelt `1e-3`, 146 parameters."""

from __future__ import annotations

import shutil
import textwrap
from pathlib import Path

import pytest

from fleet.cli import main
from fleet.errors import SpecError
from fleet.expand import expand_fleet
from fleet.expand.parameters import parse_override
from fleet.spec.load import load_spec, parse_spec
from fleet.spec.params import flatten
from fleet.spec.yaml_source import load_yaml

NAVLIKE = Path(__file__).parent / "data" / "navlike"


@pytest.fixture
def navlike(tmp_path: Path) -> Path:
    """A copy of the navlike fleet and its template, to change in a test."""
    shutil.copytree(NAVLIKE, tmp_path / "navlike")
    return tmp_path / "navlike"


def run_cli(args: list[str], capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as exited:
        main(args)
    captured = capsys.readouterr()
    return int(exited.value.code or 0), captured.out, captured.err


def refused(capsys, spec: Path, *extra: str) -> str:
    """The one error line of a render that must fail with exit 2 and write nothing."""
    out = spec.parent / "out"
    code, _, err = run_cli(["render", str(spec), "-o", str(out), *extra], capsys)
    assert code == 2, err
    assert not out.exists()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("fleet: error: "), err
    return lines[0]


def typed(value):
    """A value with the type of each scalar, so that 1 == 1.0 == True cannot pass for equal."""
    if isinstance(value, dict):
        return {key: typed(item) for key, item in value.items()}
    if isinstance(value, list):
        return [typed(item) for item in value]
    return (type(value).__name__, value)


def flat(parameters: dict) -> dict:
    return {name: value for name, (_, value) in flatten(parameters).items()}


SPEC = """\
fleet: demo
robots:
  - name: robot1
    launch_args: {log_level: 1e-3}
    parameters:
      controller:
        max_speed: 1e-1
        goal_tolerance: 5.
        control_rate: 2e1
        waypoints: [1e-3, 0.5, 1.0, 2.0]
        loop: y
"""


def test_spec_parameters_are_typed_as_rcl_types_them_and_nothing_else_is():
    spec = parse_spec(SPEC + "      battery: {capacity: 1e2}\n")
    controller = spec.robots[0].parameters["controller"]
    assert typed(controller) == {
        "max_speed": ("float", 0.1),
        "goal_tolerance": ("float", 5.0),
        "control_rate": ("float", 20.0),
        "waypoints": [("float", 0.001), ("float", 0.5), ("float", 1.0), ("float", 2.0)],
        "loop": ("bool", True),
    }
    # Outside parameters the spec keeps its YAML 1.1 reading: 1e-3 (no dot) is a string there.
    assert spec.robots[0].launch_args == {"log_level": "1e-3"}


def test_parameter_names_are_the_text_written():
    """rcl reads a key as its text; YAML 1.1 would make `on` True and `no` False."""
    text = "fleet: demo\nrobots:\n  - name: r1\n    parameters:\n      controller: {no: 1.0, y: on, pid: {on: 2}}\n"
    assert parse_spec(text).robots[0].parameters == {"controller": {"no": 1.0, "y": True, "pid": {"on": 2}}}


def test_rcl_typing_of_values_rcl_reads_differently_from_yaml_1_1():
    data, _ = load_yaml(
        textwrap.dedent(
            """\
            node:
              a: 1e-3
              b: y
              c: 1_000
              d: 010
              e: "y"
              f: !!str 5
              g: 09
              h: 0x1f
              i: n
              j: '1_000'
              k: 2024 was a year of robots, """
            + "and more " * 20
            + """
              l: 00000000000000000000000000000000000000000000000000000000000000000000000000000000000001
            """
        ),
        "defaults.yaml",
        ((None,),),
    )
    assert typed(data["node"]) == {
        "a": ("float", 0.001),
        "b": ("bool", True),
        "c": ("str", "1_000"),
        "d": ("int", 8),
        "e": ("str", "y"),
        "f": ("str", "5"),
        "g": ("float", 9.0),
        "h": ("int", 31),
        "i": ("bool", False),
        "j": ("str", "1_000"),
        "k": ("str", "2024 was a year of robots, " + "and more " * 19 + "and more"),
        "l": ("int", 1),  # octal, to strtoll
    }


def test_template_defaults_are_typed_as_rcl_types_them():
    expansion = expand_fleet(load_spec(NAVLIKE / "fleet.yaml"))
    localizer = expansion.robots[1].parameters.effective_of("localizer")
    assert typed(localizer["sensor_timeout"]) == ("float", 0.1)
    assert typed(localizer["max_lag"]) == ("float", 1e-10)
    assert typed(localizer["firmware_build"]) == ("str", "1_000")
    assert typed(localizer["calibration_id"]) == ("str", "0042")
    assert typed(localizer["imu0_remove_gravitational_acceleration"]) == ("bool", True)
    assert typed(localizer["imu0_queue_size"]) == ("int", 16)
    assert typed(localizer["debug"]) == ("bool", False)
    assert typed(localizer["initial_estimate_covariance"]) == [("float", 1e-9)] * 15
    assert localizer["process_noise_covariance"][:3] == [0.05, 0.0, 0.0]


@pytest.mark.parametrize(
    "text, expected",
    [
        ("1e-3", ("float", 0.001)),
        ("y", ("bool", True)),
        ("1_000", ("str", "1_000")),
        ("010", ("int", 8)),
        ('"y"', ("str", "y")),
        ("[1e-3, 2e-3]", [("float", 0.001), ("float", 0.002)]),
    ],
)
def test_set_values_are_typed_as_rcl_types_them(text, expected):
    assert typed(parse_override(f"robot1.controller.x={text}").value) == expected


@pytest.mark.parametrize(
    "value, problem",
    [
        ("[1, 2.5]", "mixed-type list"),
        ("[1, 1e-3]", "mixed-type list"),
        ("[true, 1]", "mixed-type list"),
        ("null", "rcl would read the string"),
        ("!!float 1", "rcl ignores tags other than !!str"),
    ],
)
def test_values_rcl_reads_otherwise_are_refused_at_their_place(tmp_path, capsys, value, problem):
    spec = tmp_path / "fleet.yaml"
    spec.write_text(SPEC + f"        goal_tolerance_list: {value}\n")
    line = refused(capsys, spec)
    assert f"{spec}:12:30: " in line and problem in line
    with pytest.raises(SpecError, match=problem.replace("!", "[!]")):
        parse_override(f"robot1.controller.x={value}")


def test_empty_parameter_value_refused_as_rcl_refuses_it(tmp_path, capsys):
    spec = tmp_path / "fleet.yaml"
    spec.write_text(SPEC + "        goal_tolerance_list:\n")
    line = refused(capsys, spec)
    assert "rcl refuses an empty parameter value" in line


def test_a_mixed_list_in_template_defaults_is_refused_at_its_place(navlike, capsys):
    defaults = navlike / "templates" / "navlike.params.yaml"
    defaults.write_text(defaults.read_text().replace("scale: 0.02", "scale: [1, 0.02]"))
    line = refused(capsys, navlike / "fleet.yaml")
    assert f"{defaults}:78:14: " in line and "mixed-type list" in line


def test_written_parameter_files_read_back_as_the_same_typed_values(tmp_path):
    """Read the written file as rcl would (fleet's rcl typing; test_params_rclpy.py does it with
    real rclpy): strings that rcl or YAML 1.1 would read as something else are quoted."""
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        # A log level 1e-3 is text, as the test above shows, and no node starts with it.
        SPEC.replace("loop: y", "loop: y\n      battery: {}").replace("log_level: 1e-3", "log_level: warn")
        + "      safety:\n"
        + "".join(
            f"        s{index}: {text}\n"
            for index, text in enumerate(['"1_000"', '"y"', '"inf"', '"nan"', '"Infinity"', '"1e-3"', '"010"', "1e-10"])
        )
    )
    expansion = expand_fleet(load_spec(spec))
    plan = expansion.robots[0]
    written = expansion.bundles[0].files["robot1.params.yaml"]
    data, _ = load_yaml(written, "robot1.params.yaml", ((None, "ros__parameters"),))
    for node in ("controller", "safety", "battery"):
        expected = plan.parameters.effective_of(node)
        got = data[f"/robot1/{node}"]["ros__parameters"]
        assert typed(flat(got)) == typed(expected)
    assert typed(data["/robot1/safety"]["ros__parameters"]["s2"]) == ("str", "inf")
    assert typed(data["/robot1/safety"]["ros__parameters"]["s7"]) == ("float", 1e-10)


# --- nodes hosted inside another node's process -----------------------------------------------


def test_hosted_nodes_get_their_own_fully_qualified_sections():
    expansion = expand_fleet(load_spec(NAVLIKE / "fleet.yaml"))
    for index, plan in enumerate(expansion.robots):
        text = expansion.bundles[index].files[f"{plan.name}.params.yaml"]
        data, _ = load_yaml(text, "params", ((None, "ros__parameters"),))
        assert list(data) == [
            f"/{plan.name}/{node}"
            for node in (
                "localizer",
                "controller_server",
                "planner_server",
                "behavior_server",
                "local_costmap/local_costmap",
                "global_costmap/global_costmap",
            )
        ]
    robot1 = expansion.robot("robot1")
    assert robot1 is not None
    local = robot1.parameters.effective_of("local_costmap/local_costmap")
    assert local["resolution"] == 0.1 and local["voxel_layer.scan.obstacle_max_range"] == 2.0
    assert local["voxel_layer.scan.obstacle_min_range"] == 0.0  # the template's, beside the robot's
    robot3 = expansion.robot("robot3")
    assert robot3 is not None
    assert (
        robot3.parameters.effective_of("global_costmap/global_costmap")["static_layer.map_subscribe_transient_local"]
        is False
    )


def test_set_and_explain_reach_hosted_nodes(capsys):
    spec = str(NAVLIKE / "fleet.yaml")
    code, out, err = run_cli(
        [
            "render",
            spec,
            "--set",
            "robot2.local_costmap/local_costmap.inflation_layer.inflation_radius=1e-1",
            "--explain",
            "robot2.local_costmap/local_costmap.inflation_layer.inflation_radius",
            "--json",
        ],
        capsys,
    )
    assert code == 0, err
    assert '"value": 0.1' in out and '"layer": "--set"' in out


@pytest.mark.parametrize(
    "node, problem",
    [
        ("local_costmap/local_cost_map", "hosts no node 'local_costmap/local_cost_map'"),
        ("/robot1/local_costmap/local_costmap", "must be relative to the robot's namespace"),
        ("local_costmap/2d", "must not start with a digit"),
        ("local-costmap/local_costmap", "not a valid ROS name"),
    ],
)
def test_hosted_node_names_are_checked(navlike, capsys, node, problem):
    spec = navlike / "fleet.yaml"
    spec.write_text(spec.read_text().replace("      local_costmap/local_costmap:", f"      {node}:"))
    line = refused(capsys, spec)
    assert f"{spec}:17:7: " in line and problem in line


def test_a_hosted_node_may_not_take_the_name_of_a_started_one(navlike, capsys):
    defaults = navlike / "templates" / "navlike.params.yaml"
    defaults.write_text(defaults.read_text() + "planner_server/x:\n  a: 1\n")
    launch = navlike / "templates" / "navlike.launch.yaml.j2"
    launch.write_text(
        launch.read_text()
        + "  - node: {pkg: fleet_test, exec: x, name: x, namespace: planner_server,"
        + " param: [{from: {{ params_file }}}]}\n"
    )
    line = refused(capsys, navlike / "fleet.yaml")
    assert "hosted node planner_server/x: the template's launch file starts a node /robot1/planner_server/x" in line


def test_hosted_nodes_need_a_process_given_the_parameter_file(navlike, capsys):
    launch = navlike / "templates" / "navlike.launch.yaml.j2"
    launch.write_text(launch.read_text().replace(", param: [{from: {{ params_file }}}]", ""))
    line = refused(capsys, navlike / "fleet.yaml")
    assert "navlike.launch.yaml.j2: parameter defaults for hosted nodes" in line
    assert "no process would read them" in line


# --- --set on a group ---------------------------------------------------------------------------


def test_set_on_a_group_is_refused_naming_the_group_and_what_to_write(capsys):
    line = refused(capsys, NAVLIKE / "fleet.yaml", "--set", "robot1.controller_server.FollowPath=dwb_core::X")
    assert "controller_server.FollowPath is a parameter in the --set layer" in line
    assert "a group of 38 parameters" in line
    assert "--set robot1.controller_server.FollowPath.plugin=..." in line
    assert " ... " not in line, "the whole message fits on its line"


# --- warnings -----------------------------------------------------------------------------------


def test_nested_parameters_the_template_knows_do_not_warn():
    expansion = expand_fleet(load_spec(NAVLIKE / "fleet.yaml"))
    assert expansion.warnings == []


def test_an_unknown_name_warns_once_with_its_near_miss(navlike):
    spec = navlike / "fleet.yaml"
    text = spec.read_text()
    text = text.replace("PathAlign: {scale: 16.0}", "PathAlign: {scale: 16.0, forward_point_distanse: 0.2}")
    text = text.replace("        max_vel_x: 0.3\n", "        max_vel_x: 0.3\n        max_vel_xx: 0.3\n")
    typo = "      controller_server: {FollowPath: {PathAlign: {forward_point_distanse: 0.3}}}\n"
    text = text.replace("      global_costmap/global_costmap:\n", typo + "      global_costmap/global_costmap:\n")
    spec.write_text(text)
    warnings = expand_fleet(load_spec(spec)).warnings
    assert len(warnings) == 2, warnings
    (defaults_typo,) = [w for w in warnings if "max_vel_xx" in w]
    assert f"{spec}:10:21: controller_server.FollowPath.max_vel_xx is not a parameter" in defaults_typo
    assert "(did you mean 'FollowPath.max_vel_x'?)" in defaults_typo
    assert "more place" not in defaults_typo  # set once, in defaults.parameters, for three robots
    (robot_typo,) = [w for w in warnings if "forward_point_distanse" in w]
    assert "(did you mean 'FollowPath.PathAlign.forward_point_distance'?) (and 1 more place)" in robot_typo
