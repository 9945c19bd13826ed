"""Every kind of bad input: exit code 2, one line naming file, line and problem, nothing written."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from fleet.cli import main
from fleet.expand import expand_fleet
from fleet.spec import parse_spec

GOOD = """\
fleet: demo
agents: {local: {}}
robots:
  - name: robot1
    parameters:
      controller: {max_speed: 0.5}
  - name: robot2
"""


def run_cli(args: list[str], capsys) -> tuple[str | int | None, str, str]:
    with pytest.raises(SystemExit) as exited:
        main(args)
    captured = capsys.readouterr()
    return exited.value.code, captured.out, captured.err


def render_bad(tmp_path: Path, capsys, spec_text: str, *extra: str) -> str:
    spec = tmp_path / "fleet.yaml"
    spec.write_text(textwrap.dedent(spec_text))
    out = tmp_path / "out"
    code, _stdout, stderr = run_cli(["render", str(spec), "-o", str(out), *extra], capsys)
    assert code == 2, stderr
    assert not out.exists(), "nothing may be written when the input is bad"
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, f"expected one line, got: {stderr!r}"
    assert "Traceback" not in stderr
    return lines[0]


@pytest.mark.parametrize(
    "spec_text, expected",
    [
        ("fleet: demo\nrobots:\n  - name: robot1\n    pose: {x: 1\n", [":5:", "YAML syntax error"]),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    parmeters: {}\n",
            [":4:5:", "unknown key 'parmeters'", "did you mean 'parameters'"],
        ),
        ("fleet: demo\nrobts:\n  - name: robot1\n", [":2:1:", "unknown key 'robts'", "did you mean 'robots'"]),
        (
            "fleet: demo\nrobots:\n  - name: r1\n    launch_args: {log_level: [a]}\n",
            [":4:30:", "a launch argument takes one value (text, a number, true or false), not a list"],
        ),
        (
            "fleet: demo\nworld: {physics_rate: 1e2}\nrobots: [{name: r1}]\n",
            [":2:23:", "got string '1e2' (YAML reads 1e2 as text: write 1.0e+2)"],
        ),
        # With a '.' but no sign in the exponent, it is text to YAML 1.1 too.
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: crate, type: box, position: [2.5, 1.5], "
            "size: [1.0e9, 0.5, 0.5]}\nrobots: [{name: r1}]\n",
            [
                ":4:61:",
                "size[0]: Input should be a valid number, got string '1.0e9' (YAML reads 1.0e9 as text: write 1.0e+9)",
            ],
        ),
        # Keys YAML 1.1 reads as other than text, named where they are.
        ("fleet: demo\nyes: 1\nrobots: [{name: r1}]\n", [":2:1:", "key bool True: keys here are names"]),
        ("fleet: demo\nagents: {5: {}}\nrobots: [{name: r1}]\n", [":2:10:", "key int 5 in agents: keys here"]),
        # The models see integers as floats; the message shows what was written.
        ("fleet: demo\nworld: {agent: 5}\nrobots: [{name: r1}]\n", [":2:16:", "world.agent:", "got int 5"]),
        # Where the spec came from is the loader's to say, not a key a spec may set.
        ("fleet: demo\nsource_file: /etc/passwd\nrobots: [{name: r1}]\n", [":2:1:", "unknown key 'source_file'"]),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    pose: {x: fast}\n",
            [":4:15:", "pose.x", "valid number", "'fast'"],
        ),
        ("fleet: demo\nros: {domain_id: seven}\nrobots: [{name: r1}]\n", [":2:", "domain_id", "integer"]),
        ("fleet: demo\nrobots:\n  - name: robot1\n  - name: robot1\n", [":4:11:", "duplicate robot name 'robot1'"]),
        ("fleet: demo\nrobots:\n  - name: 2robot\n", [":3:11:", "must not start with a digit"]),
        ("fleet: demo\nrobots:\n  - name: robot-1\n", [":3:11:", "not a valid ROS name"]),
        # Names reach nodes as remap rules (-r __ns:=/a__b), which rcl cannot parse with '__' in them.
        ("fleet: demo\nrobots:\n  - name: a__b\n", [":3:11:", "'a__b' is not a valid ROS name: '__' is reserved"]),
        ("fleet: demo\nrobots:\n  - name: r1\n    namespace: /site__a/r1\n", [":4:", "'__' is reserved"]),
        ("fleet: demo\nrobots:\n  - name: robot1\n    namespace: /site a/robot1\n", [":4:", "namespace"]),
        ("fleet: demo\nrobots:\n  - name: robot1\n    namespace: relative\n", [":4:", "absolute namespace"]),
        ("fleet: demo\nrobots:\n  - name: robot1\n    agent: hostB\n", [":4:12:", "agent 'hostB' is not declared"]),
        # Agents declared without `local`, the default nobody wrote: said at the robot left to it.
        (
            "fleet: demo\nagents: {rack: {}}\nrobots:\n  - name: r1\n    agent: rack\n  - name: r2\n",
            [
                ":6:5:",
                "robot 'r2' names no agent, and the default one, 'local', is not declared under 'agents' "
                "(declared: rack): give it `agent: rack`, or set `defaults: {agent: rack}`",
            ],
        ),
        (
            "fleet: demo\nagents: {rack: {}}\nworld: {}\nrobots: [{name: r1, agent: rack}]\n",
            [":3:1:", "the world names no agent, and the default one, 'local', is not declared"],
        ),
        (
            "fleet: demo\nagents: {rack: {}}\ndefaults: {agent: rak}\nrobots: [{name: r1}]\n",
            [":3:19:", "agent 'rak' is not declared under 'agents' (declared: rack)"],
        ),
        ("fleet: demo\nrobots:\n  - name: robot1\n    template: nosuch\n", ["template 'nosuch' not found"]),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    template: diff_drv\n",
            [":4:5:", "template 'diff_drv' not found", "; did you mean 'diff_drive'?"],
        ),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {w: [[1, 2], [3, 4]]}}\n",
            [":4:", "nested lists"],
        ),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {w: [1, two]}}\n",
            [":4:", "mixed-type list"],
        ),
        ("fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {w: null}}\n", [":4:", "null"]),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {w: [{a: 1}]}}\n",
            [":4:", "mappings inside lists"],
        ),
        ("fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {w: []}}\n", [":4:", "empty list"]),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    parameters: {navigator: {speed: 1.0}}\n",
            ["no node 'navigator'"],
        ),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n    launch_args: {enable_lasers: true}\n",
            ["no launch argument 'enable_lasers'"],
        ),
        ("fleet: demo\nrobots: []\n", [":2:", "at least one robot"]),
        ("fleet: demo\nrobots:\n  - name: robot1\n    model: {type: tank}\n", [":4:", "'light', 'husky' or 'racecar'"]),
        (
            "fleet: demo\nworld:\n  obstacles: [{name: a, type: box, position: [0, 0]}]\nrobots: [{name: r1}]\n",
            [":3:", "needs size"],
        ),
        # A list of the wrong length is reported at the list, the same too short as too long (a
        # short one once read as the key missing).
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: a, type: box, position: [0, 0], size: [0.5, 0.5]}\n"
            "robots: [{name: r1}]\n",
            [":4:52:", "world.obstacles[0].size: must be a list of 3 numbers, got a list of 2"],
        ),
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: a, type: box, size: [1, 1, 1], position: [2.5]}\n"
            "robots: [{name: r1}]\n",
            [":4:55:", "world.obstacles[0].position: must be a list of 2 numbers, got a list of 1"],
        ),
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: a, type: box, size: [1, 1, 1], position: []}\n"
            "robots: [{name: r1}]\n",
            [":4:55:", "position: must be a list of 2 numbers, got a list of 0"],
        ),
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: a, type: box, size: [1, 1, 1, 1], position: [0, 0]}\n"
            "robots: [{name: r1}]\n",
            [":4:34:", "world.obstacles[0].size: must be a list of 3 numbers, got a list of 4"],
        ),
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: a, type: box, size: [1, 1, 1], position: here}\n"
            "robots: [{name: r1}]\n",
            [":4:55:", "position: must be a list of 2 numbers, got string 'here'"],
        ),
        (
            "fleet: demo\nrobots:\n  - name: robot1\n  - name: robot1b\n    namespace: /robot1\n",
            [":5:", "namespace /robot1 already used"],
        ),
        ("- just\n- a list\n", [":1:1:", "mapping"]),
        (
            "fleet: demo\ndefaults: {isolation: thread}\nrobots: [{name: r1}]\n",
            [":2:", "defaults.isolation", "'process', 'robot' or 'agent'", "'thread'"],
        ),
        (
            "fleet: demo\nrobots:\n  - name: r1\n    isolation: hosts\n",
            [":4:", "isolation", "'process', 'robot' or 'agent'"],
        ),
        (
            "fleet: demo\ndefaults: {isolation: agent, group_size: 0}\nrobots: [{name: r1}]\n",
            [":2:42:", "defaults.group_size", "greater than or equal to 1"],
        ),
        ("fleet: demo\ndefaults: {group_size: -3}\nrobots: [{name: r1}]\n", [":2:", "group_size"]),
        (
            "fleet: demo\nagents: {local: {max_robots: 2}}\ndefaults: {isolation: agent}\n"
            "robots:\n  - name: r1\n  - name: r2\n  - name: r3\n",
            [":7:11:", "robot 'r3'", "agent 'local' holds at most 2 robots", "agents.local.max_robots", "places 3"],
        ),
        ("fleet: demo\nfleet: other\nrobots: [{name: r1}]\n", [":2:1:", "duplicate key 'fleet'"]),
        # Parameters written as a ROS parameter file writes them: rcl would read the parameter
        # `ros__parameters.max_speed`, and the node keep its own max_speed.
        (
            "fleet: demo\nrobots:\n  - name: r1\n    parameters:\n      controller:\n"
            "        ros__parameters: {max_speed: 0.5}\n",
            [":6:9:", "controller.ros__parameters.max_speed", "right under the node"],
        ),
    ],
)
def test_bad_spec(tmp_path, capsys, spec_text, expected):
    line = render_bad(tmp_path, capsys, spec_text)
    assert str(tmp_path / "fleet.yaml") in line
    for fragment in expected:
        assert fragment in line, line


@pytest.mark.parametrize(
    "override, expected",
    [
        ("robot9.controller.max_speed=0.8", "no robot 'robot9'"),
        ("robot1.navigator.max_speed=0.8", "robot robot1 has no node 'navigator'"),
        ("robto1.controller.max_speed=0.8", "no robot 'robto1' in"),
        ("robto1.controller.max_speed=0.8", "(did you mean 'robot1'?)"),
        ("robot1.controler.max_speed=0.8", "has no node 'controler' (did you mean 'controller'?)"),
        ("robot1.controller.max_speed", "expected ROBOT.NODE.PARAMETER=VALUE"),
        ("robot1.controller.max_speed=[[1]]", "nested lists"),
        ("robot1.controller.max_speed=fast", "is float in the template layer"),
        ("robot1.controller.ros__parameters.max_speed=0.8", "'ros__parameters' is fleet's to write"),
    ],
)
def test_bad_set(tmp_path, capsys, override, expected):
    line = render_bad(tmp_path, capsys, GOOD, "--set", override)
    assert f"--set {override}" in line
    assert expected in line


def write_templates(tmp_path: Path, body: str) -> Path:
    templates = tmp_path / "my_templates"
    templates.mkdir()
    (templates / "custom.launch.yaml.j2").write_text(body)
    return templates


def test_template_defaults_in_the_ros_parameter_file_form_are_refused_at_their_key(tmp_path, capsys):
    """A `.params.yaml` copied from a ROS parameter file (`controller: {ros__parameters: {...}}`):
    every default would reach the node as `ros__parameters.<name>` (rcl checked), so none would
    count; refused at the `ros__parameters` key, not warned about at the spec's values."""
    templates = write_templates(
        tmp_path,
        "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: a, exec: b, name: controller, param: [{from: {{ params_file }}}]}\n",
    )
    (templates / "custom.params.yaml").write_text("controller:\n  ros__parameters:\n    max_speed: 0.3\n")
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\n"
        "robots: [{name: r1, parameters: {controller: {max_speed: 0.5}}}]\n",
    )
    assert line.startswith(f"fleet: error: {templates / 'custom.params.yaml'}:2:3: parameter name ")
    assert line.endswith("'ros__parameters' is fleet's to write: give them right under the node (controller: {x: 1.0})")


@pytest.mark.parametrize(
    "defaults, place, got",
    [
        ("controller: {max_speed: 0.3}\nbattery:\n", ":2:1:", "got nothing"),  # was placed at line 1
        ("controller: {max_speed: 0.3}\nbattery: [1.0]\n", ":2:10:", "got a list"),
    ],
)
def test_template_defaults_of_a_node_that_are_no_mapping_are_placed_at_the_node(tmp_path, capsys, defaults, place, got):
    templates = write_templates(
        tmp_path,
        "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: a, exec: b, name: controller, param: [{from: {{ params_file }}}]}\n"
        "  - node: {pkg: a, exec: c, name: battery, param: [{from: {{ params_file }}}]}\n",
    )
    (templates / "custom.params.yaml").write_text(defaults)
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert line == (
        f"fleet: error: {templates / 'custom.params.yaml'}{place} parameter defaults of node battery: "
        f"expected a mapping of parameters (write {{}} for none), {got}"
    )


def test_template_defaults_of_a_node_the_template_does_not_start_are_placed_at_the_node(tmp_path, capsys):
    """A mistyped node name in a template's defaults (`announcr:`) was refused naming the file
    alone, with no line and no hint."""
    templates = write_templates(
        tmp_path,
        "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: a, exec: b, name: announcer, param: [{from: {{ params_file }}}]}\n",
    )
    (templates / "custom.params.yaml").write_text("announcer: {x: 1}\nannouncr:\n  x: 2\n")
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert line == (
        f"fleet: error: {templates / 'custom.params.yaml'}:2:1: defaults for node 'announcr', which template "
        "'custom' does not start (did you mean 'announcer'?) (nodes: announcer)"
    )


@pytest.mark.parametrize(
    "node, problem",
    [
        ("{pkg: a, exec: b}", "node is missing 'name'"),
        ("{pkg: a, exec: b, name: $(var who)}", "name '$(var who)' must be literal in a fleet template"),
    ],
)
def test_a_node_fleet_cannot_outline_is_placed_at_its_line_of_the_output(tmp_path, capsys, node, problem):
    """As the reader's own refusals are, and at the template's line that wrote it (the message had
    no place at all, then only the output's)."""
    templates = write_templates(
        tmp_path,
        "launch:\n- arg: {name: who, default: c}\n- group:\n"
        "  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        f"  - node: {node}\n",
    )
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert line.startswith(
        f"fleet: error: {templates / 'custom.launch.yaml.j2'}:5: rendered launch file refused: "
        f"line 5, column 5 of its output: {problem}"
    ), line


@pytest.mark.parametrize(
    "bad, place",
    [
        ("    output: log: screen\n", ":13"),  # one template line writes it
        ("    name: twin\n", ""),  # two could have: only the output's line is said
    ],
)
def test_a_template_rendering_invalid_yaml_is_placed_at_the_line_that_wrote_it(tmp_path, capsys, bad, place):
    """A template's output that is not YAML is an error of the template: at the template's line
    that wrote the bad line when only one could have (above it, a comment and lines that print
    nothing move the output's lines away from the template's), else at the output's line."""
    templates = write_templates(
        tmp_path,
        "{#- A template,\n    its comment on two lines. -#}\n"
        "launch:\n"
        "{% if true %}\n"
        "- node:\n"
        "    pkg: a\n"
        "    exec: b\n"
        "    name: twin\n"
        "- node:\n"
        "    pkg: a\n"
        "    exec: c\n"
        "    name: {{ robot.name }}\n" + bad + "{% endif %}\n",
    )
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert line.startswith(
        f"fleet: error: {templates / 'custom.launch.yaml.j2'}{place}: rendered invalid YAML at line 10 of its output: "
    ), line


def test_a_launch_argument_the_template_declares_without_arg_takes_no_value(tmp_path, capsys):
    """A value reaches a robot only through arg(), which writes it as the rendered file's default
    (agents pass no launch arguments): given for one the launch file declares as plain YAML, it was
    accepted and silently dropped (the node ran as the default said). One read through arg() but
    not declared as `- arg:` takes its value."""
    templates = write_templates(
        tmp_path,
        "launch:\n- arg: {name: lasers, default: 'true'}\n- group:\n"
        "  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: a, exec: b, name: c, if: $(var lasers), args: {{ arg('rate', 5) }}}\n",
    )
    spec = "fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots:\n- name: r1\n"
    spec += "  launch_args: {{{args}}}\n"
    line = render_bad(tmp_path, capsys, spec.format(templates=templates, args="lasers: false"))
    assert line == (
        f"fleet: error: {tmp_path / 'fleet.yaml'}:6:17: template 'custom' declares launch argument 'lasers' without "
        """arg(), so no value reaches it (write its default as {{ arg("lasers", ...) }})"""
    )
    (tmp_path / "fleet.yaml").write_text(spec.format(templates=templates, args="rate: 7"))
    expansion = expand_fleet(parse_spec((tmp_path / "fleet.yaml").read_text(), str(tmp_path / "fleet.yaml")))
    assert 'args: "7"}' in expansion.robots[0].launch_text


def test_template_syntax_error_names_template_line(tmp_path, capsys):
    templates = write_templates(tmp_path, "launch:\n- node: {pkg: a, exec: b, name: c}\n{% if robot.name %}\n")
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert f"{templates / 'custom.launch.yaml.j2'}:3" in line or f"{templates / 'custom.launch.yaml.j2'}:4" in line
    assert "template syntax error" in line


def test_template_undefined_variable_names_template_line(tmp_path, capsys):
    templates = write_templates(
        tmp_path,
        "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        "  - node: {pkg: a, exec: b, name: {{ robot.nickname }}}\n",
    )
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert f"{templates / 'custom.launch.yaml.j2'}:4:" in line
    assert "nickname" in line


@pytest.mark.parametrize(
    ("printed", "name"),
    [("namespace", "namespace"), ("range", "range"), ("dict", "dict"), ("cycler", "cycler"), ("arg", "arg")],
)
def test_template_printing_a_function_names_it(tmp_path, capsys, printed, name):
    """Jinja's globals and fleet's own functions are not data: printing one says which."""
    templates = write_templates(
        tmp_path,
        "launch:\n- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"
        f"  - node: {{pkg: a, exec: b, name: {{{{ {printed} }}}}}}\n",
    )
    line = render_bad(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: custom}}\nrobots: [{{name: r1}}]\n",
    )
    assert f"{templates / 'custom.launch.yaml.j2'}:4:" in line
    assert f"'{name}' is a function, not a value" in line


def test_missing_spec_file(tmp_path, capsys):
    code, _, stderr = run_cli(["render", str(tmp_path / "nope.yaml")], capsys)
    assert code == 2 and "no such fleet spec file" in stderr and str(tmp_path / "nope.yaml") in stderr


def test_real_process_error_is_one_line_exit_2(tmp_path):
    """The installed command, as a user runs it: no traceback, exit 2, nothing written."""
    spec = tmp_path / "bad.yaml"
    spec.write_text("fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {max_speed: [1, [2]]}}\n")
    result = subprocess.run(
        [sys.executable, "-m", "fleet", "render", str(spec), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 2
    assert result.stderr.count("\n") == 1 and "Traceback" not in result.stderr
    assert f"{spec}:4:" in result.stderr and "nested lists" in result.stderr
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "spec_text, expected",
    [
        # The world's limits (fleet/world/description.py), placed where the spec writes the value.
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: crate, type: box, position: [2.5, 1.5], "
            "size: [1.0e+300, 0.5, 0.5]}\nrobots: [{name: r1}]\n",
            ":4:61: obstacle 'crate': 'size' must be at most 10000 m (the world is 10000 m across), got 1e+300",
        ),
        (
            "fleet: demo\nworld:\n  obstacles:\n    - {name: silo, type: cylinder, position: [9000, 0], radius: 1}\n"
            "robots: [{name: r1}]\n",
            ":4:47: obstacle 'silo': 'position' must be in -5000..5000 m (the world's extent), got 9000",
        ),
        (
            "fleet: demo\nworld: {}\nrobots:\n  - {name: r0, simulated: false}\n  - {name: r1, pose: {x: 4.0e+5}}\n",
            ":5:26: robot 'r1'.pose: 'x' must be in -5000..5000 m (the world's extent), got 400000",
        ),
        (
            "fleet: demo\nworld: {physics_rate: 0.001}\nrobots: [{name: r1}]\n",
            ":2:23: world: 'physics_rate' must be at least 50 steps a second",
        ),
        (
            "fleet: demo\nworld: {physics_rate: 240, clock_rate: 1000}\nrobots: [{name: r1}]\n",
            ":2:40: clock_rate 1000 Hz is faster than the world publishes it (once per physics step at "
            "physics_rate 240): at most 240 Hz",
        ),
        (
            "fleet: demo\nworld: {physics_rate: 60, odom_rate: 100}\nrobots: [{name: r1}]\n",
            ":2:38: robot 'r1': odom_rate 100 Hz is faster than the world publishes it (once per physics step "
            "at physics_rate 60): at most 60 Hz",
        ),
        # A robot's lidar from `defaults` is placed there, its own lidar at the robot.
        (
            "fleet: demo\nworld: {}\ndefaults: {lidar: {rate: 100}}\nrobots: [{name: r1}]\n",
            ":3:26: robot 'r1': lidar rate 100 Hz is faster than the world publishes it (once every 4 physics "
            "steps at physics_rate 240): at most 60 Hz",
        ),
        (
            "fleet: demo\nworld: {}\nrobots: [{name: r1}, {name: r2, lidar: {rate: 61}}]\n",
            ":3:47: robot 'r2': lidar rate 61 Hz",
        ),
        (
            "fleet: demo\nworld: {}\ndefaults:\n  lidar: {range_min: 5, range_max: 1}\nrobots: [{name: r1}]\n",
            ":4:22: robot 'r1'.lidar: range_min must be below range_max",
        ),
    ],
)
def test_what_the_world_would_not_hold_is_refused_at_render(tmp_path, capsys, spec_text, expected):
    line = render_bad(tmp_path, capsys, spec_text)
    assert line.startswith(f"fleet: error: {tmp_path / 'fleet.yaml'}{expected}"), line


def test_the_default_clock_rate_follows_a_slow_physics(tmp_path, capsys):
    spec = tmp_path / "fleet.yaml"
    spec.write_text("fleet: demo\nworld: {physics_rate: 50}\nrobots: [{name: r1}]\n")
    code, _, stderr = run_cli(["render", str(spec), "-o", str(tmp_path / "out")], capsys)
    assert code in (0, None), stderr
    assert "\nclock_rate: 50.0\n" in (tmp_path / "out" / "world" / "world.yaml").read_text()


def test_a_launch_argument_number_yaml_reads_as_text_says_how_to_write_it(tmp_path, capsys):
    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "custom.launch.yaml.j2").write_text(
        'launch:\n- arg: {name: speed, default: {{ arg("speed", 1.5) }}}\n'
    )
    robot = "{name: r1, template: custom, launch_args: {speed: 2.5e3}}"
    line = render_bad(tmp_path, capsys, f"fleet: demo\ntemplates: {templates}\nrobots:\n  - {robot}\n")
    assert "is a number (its default is 1.5), got '2.5e3' (YAML reads 2.5e3 as text: write 2.5e+3)" in line, line
