"""`fleet render` refuses a parameter value fleet's own nodes (package fleet_nodes) would refuse
at start, of the wrong type or out of the range they declare, and values they refuse together
(waypoints not in x,y pairs, a critical battery threshold above the low one), by their own
declarations and rules (fleet.nodes.parameters): at the place the value is given, before
anything is deployed.  A deploy with `--set robot1.controller.max_speed=9.0` used to pass every
check and stop a working robot1 for a controller that then crash-looped; so did one with
`--set robot2.controller.waypoints=[1.0,2.0,3.0]` until the rules were checked too."""

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


def controller_given(tmp_path: Path, inline: str, parameters: str = "", with_file: bool = True) -> Path:
    """The scout template, its controller given `inline` after the robot's parameter file (or
    instead of it: `with_file` False)."""
    templates = tmp_path / "templates"
    templates.mkdir()
    given = "{from: {{ params_file }}}, " + inline if with_file else inline
    (templates / "scout.launch.yaml.j2").write_text(SCOUT.replace("{from: {{ params_file }}}]", given + "]", 1))
    return spec_file(
        tmp_path,
        "fleet: demo\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: scout}\n"
        f"robots:\n- {{name: a{parameters}}}\n",
    )


def test_a_value_the_launch_file_gives_inline_is_checked_there(tmp_path):
    """What the node gets is what is checked: a value given inline after the parameter file wins
    over the file's, so it is refused at its line of the rendered launch file."""
    spec = controller_given(tmp_path, "{name: max_speed, value: 7.5}")
    with pytest.raises(SpecError) as refused:
        expand_fleet(parse_spec(spec.read_text(), str(spec)))
    assert str(refused.value).startswith("a/a.launch.yaml:4:")
    assert "robot a: controller.max_speed = 7.5 is out of range 0.0 .. 5.0" in str(refused.value)


def test_robots_that_share_their_nodes_parameters_are_checked_once(monkeypatch):
    """Cheap for 10,000 robots: a node's values no robot changed are checked once, not per robot,
    and so are its rules."""
    from fleet.nodes.parameters import ParamSpec, Rule

    calls = []
    rules = []
    real, real_rule = ParamSpec.problem, Rule.problem

    def counted(self, value):
        calls.append(self.name)
        return real(self, value)

    def counted_rule(self, values):
        rules.append(self.names)
        return real_rule(self, values)

    monkeypatch.setattr(ParamSpec, "problem", counted)
    monkeypatch.setattr(Rule, "problem", counted_rule)
    robots = "".join(f"  - {{name: r{i}}}\n" for i in range(200))
    expand_fleet(parse_spec("fleet: demo\nros: {use_sim_time: false}\nrobots:\n" + robots, "f.yaml"))
    assert 0 < len(calls) <= 16  # the 16 parameters of controller, battery and safety, once
    assert 0 < len(rules) <= 3  # the controller's rule and the battery's two, once


# -- the nodes' checks of their values together (fleet.nodes.parameters' rules) ---------------

ODD = "waypoints must be x,y pairs (even length >= 2), got 3 values"


def test_waypoints_set_in_odd_number_are_refused_at_the_set(capsys):
    assert refusal(capsys, TWO_ROBOTS, "--set", "robot2.controller.waypoints=[1.0,2.0,3.0]") == (
        f"fleet: error: --set robot2.controller.waypoints=[1.0,2.0,3.0]: robot robot2: controller.{ODD} "
        "(fleet_nodes controller refuses it at start)"
    )
    capsys.readouterr()
    assert run_fleet(["deploy", str(TWO_ROBOTS), "--dry-run", "--set", "robot1.controller.waypoints=[1.0]"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "controller.waypoints must be x,y pairs (even length >= 2), got 1 values" in err


def test_waypoints_in_odd_number_in_the_spec_are_refused_where_they_are_written(tmp_path, capsys):
    spec = scout(tmp_path, "{name: a, parameters: {controller: {waypoints: [1.0, 2.0, 3.0]}}}")
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:6:50: robot a: controller.{ODD} (fleet_nodes controller refuses it at start)"
    )


BATTERY = """\
launch:
- group:
  - push_ros_namespace: {namespace: {{ robot.namespace }}}
  - node: {pkg: fleet_nodes, exec: battery, name: battery, param: [{from: {{ params_file }}}]}
"""


def battery(tmp_path: Path, robot: str, defaults: str = "") -> Path:
    """A template starting fleet_nodes' battery, with `defaults` as its parameter defaults (none:
    the node's own defaults, low_threshold 0.2 and critical_threshold 0.05)."""
    templates = tmp_path / "templates"
    templates.mkdir(parents=True, exist_ok=True)
    (templates / "cell.launch.yaml.j2").write_text(BATTERY)
    if defaults:
        (templates / "cell.params.yaml").write_text(defaults)
    return spec_file(
        tmp_path,
        "fleet: demo\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: cell}\n"
        f"robots:\n- {robot}\n",
    )


def test_values_fine_alone_but_refused_together_are_refused(tmp_path, capsys):
    """critical_threshold 0.5 is in its range 0.0 .. 1.0, but above the node's low_threshold (its
    own default, 0.2, as the node has it: no layer gives one)."""
    spec = battery(tmp_path, "{name: a, parameters: {battery: {critical_threshold: 0.5}}}")
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:6:56: robot a: battery.critical_threshold (0.5) must be <= low_threshold (0.2) "
        "(fleet_nodes battery refuses it at start)"
    )
    # With a low threshold above it, the node takes it.
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "ok"), "--set", "a.battery.low_threshold=0.6"]) == 0


def test_a_refusal_together_is_placed_at_the_value_given_last(tmp_path, capsys):
    """The refusal is placed at the value of those the rule reads in the highest layer: here the
    --set that lowered low_threshold under the template's critical_threshold."""
    spec = battery(tmp_path, "{name: a}", "battery: {critical_threshold: 0.1}\n")
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "ok")]) == 0
    assert refusal(capsys, spec, "--set", "a.battery.low_threshold=0.05") == (
        "fleet: error: --set a.battery.low_threshold=0.05: robot a: battery.critical_threshold (0.1) must be <= "
        "low_threshold (0.05) (fleet_nodes battery refuses it at start)"
    )


def test_the_templates_defaults_are_the_values_the_node_has(tmp_path, capsys):
    """critical_threshold 0.15 is below the node's own low_threshold (0.2), but the template's
    defaults give it 0.1: the node would refuse it."""
    spec = battery(tmp_path, "{name: a, parameters: {battery: {critical_threshold: 0.15}}}")
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "ok")]) == 0
    spec = battery(
        tmp_path / "low",
        "{name: a, parameters: {battery: {critical_threshold: 0.15}}}",
        "battery: {low_threshold: 0.1}\n",
    )
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:6:56: robot a: battery.critical_threshold (0.15) must be <= low_threshold (0.1) "
        "(fleet_nodes battery refuses it at start)"
    )


def test_a_capacity_of_zero_is_refused(tmp_path, capsys):
    """0.0 is the bottom of capacity's declared range, whose bounds are in; the node wants more."""
    spec = battery(tmp_path, "{name: a, parameters: {battery: {capacity: 0}}}")
    assert refusal(capsys, spec) == (
        f"fleet: error: {spec}:6:46: robot a: battery.capacity must be > 0, got 0.0 "
        "(fleet_nodes battery refuses it at start)"
    )


def test_waypoints_the_launch_file_gives_inline_are_checked_there(tmp_path):
    spec = controller_given(tmp_path, "{name: waypoints, value: [1.0, 2.0, 3.0]}")
    with pytest.raises(SpecError) as refused:
        expand_fleet(parse_spec(spec.read_text(), str(spec)))
    assert str(refused.value).startswith("a/a.launch.yaml:4:")
    assert f"robot a: controller.{ODD}" in str(refused.value)


@pytest.mark.parametrize("inline", ["{name: waypoints, value: $(env ROUTE)}", "{name: max_speed, value: $(env SPEED)}"])
def test_values_only_the_agents_computer_can_tell_are_left_to_the_node(tmp_path, inline):
    """A value of the agent's environment wins over the parameter file's: render cannot tell it,
    so it checks neither it alone (it used to refuse `$(env SPEED)` as a string) nor the rule that
    reads it, even over the spec's waypoints, which the node never gets."""
    spec = controller_given(tmp_path, inline, ", parameters: {controller: {waypoints: [1.0, 2.0, 3.0]}}")
    if "max_speed" in inline:  # the spec's waypoints reach the node: refused
        with pytest.raises(SpecError, match="got 3 values"):
            expand_fleet(parse_spec(spec.read_text(), str(spec)))
        spec.write_text(spec.read_text().replace(", parameters: {controller: {waypoints: [1.0, 2.0, 3.0]}}", ""))
    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "out")]) == 0


def test_an_environment_variable_with_a_default_is_left_to_the_agent_and_explained_as_written(tmp_path):
    """`$(env SPEED 9.0)` is the agent's SPEED when it has one; the default counts only where it
    has none, which render cannot tell.  Render used to take the default as the value: it refused
    the template for a default the agent's environment overrides, and `--explain` called the
    default effective (or, without a default, showed fleet's internal marker)."""
    from fleet.cli.plan_view import explain_data

    given = ("{name: max_speed, value: $(env SPEED 9.0)}", "{name: max_speed, value: $(env SPEED)}")
    for number, inline in enumerate(given):
        (tmp_path / str(number)).mkdir()
        spec = controller_given(tmp_path / str(number), inline)
        expansion = expand_fleet(parse_spec(spec.read_text(), str(spec)))
        written = inline.split("value: ")[1].rstrip("}")
        assert explain_data(expansion, "a.controller.max_speed")["value"] == written


def test_a_node_started_without_the_parameter_file_is_checked_by_what_it_is_given_inline(tmp_path, capsys):
    spec = controller_given(tmp_path, "{name: waypoints, value: [1.0]}", with_file=False)
    with pytest.raises(SpecError) as refused:
        expand_fleet(parse_spec(spec.read_text(), str(spec)))
    assert str(refused.value).startswith("a/a.launch.yaml:4:")
    assert "controller.waypoints must be x,y pairs (even length >= 2), got 1 values" in str(refused.value)
