"""`fleet render` refuses a parameter value fleet's own nodes (package fleet_nodes) would refuse
at start, of the wrong type or out of the range they declare, by their own declarations
(fleet.nodes.parameters): at the place the value is given, before anything is deployed.  A
deploy with `--set robot1.controller.max_speed=9.0` used to pass every check and stop a working
robot1 for a controller that then crash-looped."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from fleet.errors import SpecError
from fleet.expand import expand_fleet
from fleet.spec import parse_spec
from tests.checkout import FLEETS, run_fleet

TWO_ROBOTS = FLEETS / "two_robots.yaml"


def refusal(capsys, spec: Path, *extra: str) -> str:
    """The one error line of a render that must fail with exit 2 and write nothing."""
    out = spec.parent / "out" if spec.parent != FLEETS else None
    capsys.readouterr()
    args = ["render", str(spec), *extra] + (["-o", str(out)] if out else [])
    assert run_fleet(args) == 2
    stderr = capsys.readouterr().err
    assert stderr.count("\n") == 1 and stderr.startswith("fleet: error: "), stderr
    assert out is None or not out.exists()
    return stderr.rstrip("\n")


def spec_file(tmp_path: Path, text: str) -> Path:
    spec = tmp_path / "fleet.yaml"
    spec.write_text(textwrap.dedent(text))
    return spec


def test_a_set_value_out_of_the_nodes_range_is_refused_at_the_set(capsys):
    assert refusal(capsys, TWO_ROBOTS, "--set", "robot1.controller.max_speed=9.0") == (
        "fleet: error: --set robot1.controller.max_speed=9.0: robot robot1: controller.max_speed = 9.0 "
        "is out of range 0.0 .. 5.0 (fleet_nodes controller refuses it at start)"
    )


def test_deploy_refuses_it_before_asking_any_agent(capsys):
    """Deploy expands first: it refuses the value without a daemon or an agent to ask."""
    capsys.readouterr()
    assert run_fleet(["deploy", str(TWO_ROBOTS), "--dry-run", "--set", "robot2.battery.initial_percentage=1.5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "battery.initial_percentage = 1.5 is out of range 0.0 .. 1.0" in err, err


def test_values_out_of_range_in_the_spec_are_refused_where_they_are_written(tmp_path, capsys):
    spec = spec_file(
        tmp_path,
        """\
        fleet: demo
        ros: {use_sim_time: false}
        defaults:
          parameters:
            battery: {capacity: 50.0}
        robots:
          - name: a
          - name: b
            parameters:
              safety: {scan_timeout: 0.01}
        """,
    )
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:10:30: robot b: safety.scan_timeout = 0.01 is out of range 0.05 .. 60.0 "
        "(fleet_nodes safety refuses it at start)"
    )
    spec.write_text(spec.read_text().replace("capacity: 50.0", "capacity: -1.0"))
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:5:25: robot a: battery.capacity = -1.0 is out of range 0.0 .. 100000.0 "
        "(fleet_nodes battery refuses it at start)"
    )


SCOUT = """\
launch:
- group:
  - push_ros_namespace: {namespace: {{ robot.namespace }}}
  - node: {pkg: fleet_nodes, exec: controller, name: controller, param: [{from: {{ params_file }}}]}
  - node: {pkg: vendor_nav, exec: controller, name: planner, param: [{from: {{ params_file }}}]}
"""


def scout(tmp_path: Path, robot: str) -> Path:
    """A template without parameter defaults, so no type is fixed by a layer below the spec's:
    fleet_nodes' controller, and another package's controller (named planner)."""
    templates = tmp_path / "templates"
    templates.mkdir(exist_ok=True)
    (templates / "scout.launch.yaml.j2").write_text(SCOUT)
    return spec_file(
        tmp_path,
        "fleet: demo\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: scout}\n"
        f"robots:\n- {robot}\n",
    )


@pytest.mark.parametrize(
    "value, problem",
    [
        ("fast", "must be of type double, got string 'fast'"),
        ("true", "must be of type double, got bool True"),
        ("[1.0, 2.0]", "must be of type double, got double_array [1.0, 2.0]"),
    ],
)
def test_a_value_of_the_wrong_type_is_refused(tmp_path, capsys, value, problem):
    spec = scout(tmp_path, f"{{name: a, parameters: {{controller: {{max_speed: {value}}}}}}}")
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:6:50: robot a: controller.max_speed {problem} "
        "(fleet_nodes controller refuses it at start)"
    )


def test_a_wrong_type_given_with_set_is_refused_at_the_set(tmp_path, capsys):
    spec = scout(tmp_path, "{name: a}")
    assert refusal(capsys, spec, "--set", "a.controller.loop=1") == (
        "fleet: error: --set a.controller.loop=1: robot a: controller.loop must be of type bool, got integer 1 "
        "(fleet_nodes controller refuses it at start)"
    )


def test_values_the_nodes_take_render(tmp_path):
    """The range's edges, an integer for a double (the node takes it as the number), lists."""
    spec = scout(
        tmp_path,
        "{name: a, parameters: {controller: {max_speed: 5, max_turn_rate: 0.0, goal_tolerance: 0.01, "
        "loop: false, waypoints: [1, 2, 3, 4]}}}",
    )
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "out")]) == 0
    expansion = expand_fleet(parse_spec(TWO_ROBOTS.read_text(), str(TWO_ROBOTS)), ["robot1.controller.max_speed=5.0"])
    robot1 = expansion.robot("robot1")
    assert robot1 is not None and robot1.parameters.effective()["controller"]["max_speed"] == 5.0


def test_a_node_of_another_package_is_not_checked(tmp_path):
    """planner runs vendor_nav's controller, whose parameters fleet cannot know: even a name
    fleet_nodes' controller declares is its own business."""
    spec = scout(
        tmp_path,
        "{name: a, parameters: {planner: {max_speed: 9.0, loop: 1}, controller: {max_speed: 4.0}}}",
    )
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "out")]) == 0
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "out"), "--set", "a.planner.max_speed=20.0"]) == 0


def test_a_value_the_launch_file_gives_inline_is_checked_there(tmp_path):
    """What the node gets is what is checked: a value given inline after the parameter file wins
    over the file's, so it is refused at its line of the rendered launch file."""
    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "scout.launch.yaml.j2").write_text(
        SCOUT.replace("{from: {{ params_file }}}]", "{from: {{ params_file }}}, {name: max_speed, value: 7.5}]", 1)
    )
    spec = spec_file(
        tmp_path,
        "fleet: demo\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: scout}\n"
        "robots:\n- {name: a}\n",
    )
    with pytest.raises(SpecError) as refused:
        expand_fleet(parse_spec(spec.read_text(), str(spec)))
    assert str(refused.value).startswith("a/a.launch.yaml:4:")
    assert "robot a: controller.max_speed = 7.5 is out of range 0.0 .. 5.0" in str(refused.value)


def test_robots_that_share_their_nodes_parameters_are_checked_once(monkeypatch):
    """Cheap for 10,000 robots: a node's values no robot changed are checked once, not per robot."""
    from fleet.nodes.parameters import ParamSpec

    calls = []
    real = ParamSpec.problem

    def counted(self, value):
        calls.append(self.name)
        return real(self, value)

    monkeypatch.setattr(ParamSpec, "problem", counted)
    robots = "".join(f"  - {{name: r{i}}}\n" for i in range(200))
    expand_fleet(parse_spec("fleet: demo\nros: {use_sim_time: false}\nrobots:\n" + robots, "f.yaml"))
    assert 0 < len(calls) <= 16  # the 16 parameters of controller, battery and safety, once
