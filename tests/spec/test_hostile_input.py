"""Hostile and unusual specs, as a user's command line meets them: each is refused quickly with
one line (`fleet: error: FILE:LINE:COL: problem`, at most 300 printable characters), exit code 2,
and nothing written."""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from fleet.errors import MAX_LINE
from tests.spec.test_bad_input import render_bad


def refused(tmp_path: Path, capsys, text: str, *extra: str) -> str:
    """The error line of rendering `text` (checked: one line, exit 2, nothing written)."""
    line = render_bad(tmp_path, capsys, text, *extra)
    assert len(line) <= MAX_LINE and line.isprintable(), line
    return line


ALIAS_BOMB = "fleet: demo\n" + "".join(
    f"l{level}: &l{level} [{', '.join([f'*l{level - 1}'] * 10) if level else ', '.join(['x'] * 10)}]\n"
    for level in range(9)
)

ROBOT = "fleet: demo\nrobots:\n  - name: robot1\n"


@pytest.mark.parametrize(
    "spec_text, expected",
    [
        # numbers
        (ROBOT + "    pose: {x: " + "9" * 5000 + "}\n", [":4:15:", "number of 5000 characters"]),
        (ROBOT + "    parameters: {controller: {max_speed: 9223372036854775808}}\n", [":4:", "64-bit range"]),
        (ROBOT + "    pose: {x: .nan}\n", [":4:15:", "NaN and infinity are not accepted"]),
        (ROBOT + "    parameters: {controller: {max_speed: -.inf}}\n", [":4:", "NaN and infinity"]),
        (ROBOT + "    pose: {y: 1.0e+400}\n", [":4:15:", "too large for a float"]),
        # In parameters rcl's strtod refuses them, and rcl reads the text: refused as nan is.
        (
            ROBOT + "    parameters: {controller: {timeout: 1.0e+400}}\n",
            [":4:", "1.0e+400 is beyond the range of a double"],
        ),
        (ROBOT + "    parameters: {controller: {timeout: [1.0, 1e-400]}}\n", [":4:", "1e-400 is beyond the range"]),
        (ROBOT + "    parameters: {controller: {timeout: 0x1p99999}}\n", [":4:", "0x1p99999 is beyond the range"]),
        (
            "fleet: demo\nworld:\n  obstacles: [{name: b, type: box, position: [3, 3], size: [1, .inf, 1]}]\n"
            "robots: [{name: r1}]\n",
            [":3:", "NaN and infinity"],
        ),
        # structure
        (ROBOT + "    parameters: {controller: {x: " + "[" * 10000 + "]" * 10000 + "}}\n", ["nested", "too deep"]),
        ("fleet: demo\nrobots: &r\n  - name: r1\n    parameters: *r\n", [":4:17:", "refers to the collection"]),
        (ALIAS_BOMB + "robots: [{name: r1}]\n", ["aliases expand this document to more than"]),
        ("fleet: demo\nrobots:\n  - !robot {name: r1}\n", [":3:5:", "YAML tag !robot is not supported"]),
        (ROBOT + "    parameters: !!python/object:os.system {}\n", ["YAML tag !!python/object:os.system"]),
        ("fleet: demo\nrobots: !!set {r1: null}\n", ["YAML tag !!set"]),
        ("fleet: demo\n---\nfleet: other\n", [":2:1:", "second YAML document"]),
        # names that collide with what fleet runs
        ("fleet: demo\nworld: {}\nrobots:\n  - name: world\n", [":4:11:", "'world' is reserved"]),
        (ROBOT + "    template: world\n", [":4:15:", "runs the fleet's shared world"]),
        ("fleet: demo\ndefaults: {template: world}\nrobots: [{name: r1}]\n", [":2:", "runs the fleet's shared world"]),
        (ROBOT + "    template: ../templates/diff_drive\n", [":4:15:", "not a template name", "not a path"]),
        (ROBOT + "    template: /etc/passwd\n", ["not a template name"]),
        (ROBOT + "    namespace: /" + "a" * 250 + "\n", [":4:", "at most 245"]),
        (ROBOT + "    namespace: /" + "/".join(["abcdefghi"] * 22) + "\n", [":4:", "at most 247"]),
        # what the world would refuse
        (
            "fleet: demo\nworld: {}\nrobots:\n  - name: r1\n  - name: r2\n    pose: {x: 0.3}\n",
            [":6:", "overlaps robot 'r1'"],
        ),
        (
            "fleet: demo\nworld:\n  obstacles: [{name: crate, type: box, position: [1, 0], size: [1, 1, 1]}]\n"
            "robots:\n  - name: r1\n    pose: {x: 0.6}\n",
            [":6:", "overlaps obstacle 'crate'"],
        ),
        (
            "fleet: demo\nworld: {}\nrobots:\n  - name: r1\n    lidar: {range_min: 5, range_max: 1}\n",
            [":5:", "range_min must be below range_max"],
        ),
        # parameters and launch arguments
        (ROBOT + "    parameters: {controller: {pid.kp: 1.0, pid: {kp: 2.0}}}\n", [":4:", "pid.kp is written twice"]),
        (
            ROBOT + "    parameters: {controller: {max_speed: 1.0, max_speed.x: 2.0}}\n",
            [":4:", "max_speed is both a parameter and the namespace of controller.max_speed.x"],
        ),
        (ROBOT + "    launch_args: {enable_safety: 7}\n", [":4:", "enable_safety is true or false", "got 7"]),
        (ROBOT + "    launch_args: {enable_safety: maybe}\n", [":4:", "enable_safety is true or false"]),
    ],
)
def test_hostile_spec(tmp_path, capsys, spec_text, expected):
    start = time.monotonic()
    line = refused(tmp_path, capsys, spec_text)
    assert time.monotonic() - start < 20  # refused, not ground through (a hang would time out)
    assert str(tmp_path / "fleet.yaml") in line
    for fragment in expected:
        assert fragment in line, line


def test_a_spec_that_renders_fine_with_a_world(tmp_path, capsys):
    """The checks above refuse only what is wrong: a spec close to each limit renders."""
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        "fleet: demo\nworld:\n  obstacles: [{name: crate, type: box, position: [1, 0], size: [1, 1, 1]}]\n"
        "robots:\n  - name: r1\n    pose: {x: 0.25}\n  - name: r2\n    pose: {x: -0.2}\n"
        "    namespace: /" + "/".join(["abcdefghi"] * 20) + "\n"
        # The nodes' own ranges' edges, and values near rcl's limits for parameters they do not declare.
        "    parameters: {controller: {max_speed: 5.0, gain: 9.0e+300}, "
        "battery: {capacity: 100000.0, charge: 9223372036854775807.0}}\n"
        "    launch_args: {enable_safety: 'false', log_level: DEBUG}\n"
        "  - {name: r3, pose: {x: 9}, lidar: {range_min: 0.5, range_max: 0.6}}\n"
    )
    from tests.checkout import run_fleet

    assert run_fleet(["render", str(spec), "-o", str(tmp_path / "out")]) == 0, capsys.readouterr().err


def test_control_characters_and_huge_values_stay_on_one_short_line(tmp_path, capsys):
    line = refused(tmp_path, capsys, 'fleet: demo\nrobots:\n  - name: "r1\\nfleet: error: forged \\e[31m\\0"\n')
    assert "\\nfleet: error: forged \\x1b[31m\\x00" in line
    line = refused(tmp_path, capsys, ROBOT + "    " + "k" * 1000 + ": 1\n")
    assert "unknown key 'kkkkk" in line and "..." in line


def test_hostile_set_arguments(tmp_path, capsys):
    good = "fleet: demo\nrobots:\n  - name: robot1\n    parameters: {controller: {pid: {kp: 1.0}}}\n"
    line = refused(tmp_path, capsys, good, "--set", "robot1.controller.max-speed=1")
    assert "--set robot1.controller.max-speed=1" in line and "not a valid ROS name" in line
    line = refused(tmp_path, capsys, good, "--set", "robot1.contr oller.max_speed=1")
    assert "node name" in line
    line = refused(tmp_path, capsys, good, "--set", "robot1.controller.pid=2")
    assert "pid is a parameter in the --set layer" in line and "namespace of controller.pid.kp" in line
    line = refused(tmp_path, capsys, good, "--set", "robot1.controller.max_speed=.nan")
    assert "NaN and infinity" in line
    line = refused(tmp_path, capsys, good, "--set", "robot1.controller.max_speed=&a [*a]")
    assert "refers to the collection" in line
    line = refused(tmp_path, capsys, good, "--set", "robot1.controller.max_speed=1\nfleet: error: forged")
    assert "\\nfleet: error: forged" in line


def test_missing_include_and_self_include_in_a_template(tmp_path, capsys):
    templates = tmp_path / "my_templates"
    templates.mkdir()
    (templates / "custom.launch.yaml.j2").write_text("launch:\n{% include 'missing.j2' %}\n")
    (templates / "loop.launch.yaml.j2").write_text("launch:\n{% include 'loop.launch.yaml.j2' %}\n")
    for name, expected in (("custom", "includes 'missing.j2'"), ("loop", "includes or calls itself")):
        line = refused(
            tmp_path,
            capsys,
            f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: {name}}}\nrobots: [{{name: r1}}]\n",
        )
        assert f"{templates / name}.launch.yaml.j2" in line and expected in line, line


@pytest.mark.parametrize(
    "body, expected",
    [
        ('{{ "x" * 1000000000 }}', "items repeated 1000000000 times are larger than a launch file can be"),
        ("{{ 10 ** 10000000 }}", "10 ** 10000000 has more than 4096 bits"),
        ('{{ "x" | center(1000000000) }}', "a count or width of 1000000000 is larger than a launch file can be"),
        ('{% for i in range(100000) %}{{ "x" * 1000 }}{% endfor %}', "its output is larger than 16777216 characters"),
    ],
)
def test_a_template_that_asks_for_too_much(tmp_path, capsys, body, expected):
    """Memory bombs in a template are refused before they are built (or, for output, as it grows)."""
    templates = tmp_path / "my_templates"
    templates.mkdir()
    (templates / "greedy.launch.yaml.j2").write_text(f"launch:\n# {body}\n")
    started = time.monotonic()
    line = refused(
        tmp_path,
        capsys,
        f"fleet: demo\ntemplates: {templates}\ndefaults: {{template: greedy}}\nrobots: [{{name: r1}}]\n",
    )
    assert f"{templates / 'greedy'}.launch.yaml.j2:2:" in line or f"{templates / 'greedy'}.launch.yaml.j2:" in line, (
        line
    )
    assert "template asks for too much" in line and expected in line, line
    assert time.monotonic() - started < 30  # refused at once, not after building gigabytes


def test_a_template_that_never_ends_is_stopped(tmp_path):
    """A loop of ten billion empty steps is stopped at the time limit, with the template's name."""
    from fleet.errors import Location, TemplateError
    from fleet.expand.templating import TemplateSet

    (tmp_path / "endless.launch.yaml.j2").write_text(
        "launch:\n{% for i in range(100000) %}{% for j in range(100000) %}{% endfor %}{% endfor %}\n"
    )
    templates = TemplateSet([tmp_path], render_seconds=0.5)
    started = time.monotonic()
    with pytest.raises(TemplateError, match=r"endless.launch.yaml.j2: template took more than 0.5 s to render"):
        templates.render("endless", {}, {}, Location("spec.yaml"))
    assert time.monotonic() - started < 20


def test_templates_directory_that_is_missing(tmp_path, capsys):
    line = refused(tmp_path, capsys, "fleet: demo\ntemplates: nowhere\nrobots: [{name: r1}]\n")
    assert f"{tmp_path / 'fleet.yaml'}:2:" in line and "templates directory nowhere does not exist" in line


@pytest.mark.parametrize(
    "content, expected",
    [
        (b"fleet: demo\nrobots: [{name: r\xff1}]\n", ":2: cannot read fleet spec file: not UTF-8 text"),
        (b"fleet: demo\nrobots: [{name: r\x001}]\n", ":2:18: YAML syntax error: character '\\x00' is not allowed"),
    ],
)
def test_unreadable_bytes(tmp_path, capsys, content, expected):
    spec = tmp_path / "fleet.yaml"
    spec.write_bytes(content)
    from tests.spec.test_bad_input import run_cli

    code, _, stderr = run_cli(["render", str(spec)], capsys)
    assert code == 2 and stderr.count("\n") == 1 and expected in stderr, stderr


def test_endless_file_is_refused_after_its_limit(capsys):
    """/dev/zero never ends: it is read up to the size limit, not until memory runs out."""
    from tests.spec.test_bad_input import run_cli

    code, _, stderr = run_cli(["render", "/dev/zero"], capsys)
    assert code == 2 and "/dev/zero: fleet spec file is larger than" in stderr, stderr


def test_templates_directory_that_is_a_file(tmp_path, capsys):
    (tmp_path / "templates").write_text("")
    line = refused(tmp_path, capsys, "fleet: demo\ntemplates: templates\nrobots: [{name: r1}]\n")
    assert f"{tmp_path / 'fleet.yaml'}:2:" in line and "templates directory templates is not a directory" in line
