"""Whatever a template computes, rendering it either works or is refused as the template's one
line (file and line, exit 2): never a traceback."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.checkout import run_fleet

NAMESPACE = "- group:\n  - push_ros_namespace: {namespace: {{ robot.namespace }}}\n"


def render_template(tmp_path: Path, body: str, robot: str = "{name: r1}") -> tuple[int, Path]:
    """`fleet render` of one robot on a template whose lines after `launch:` are `body`."""
    templates = tmp_path / "templates"
    templates.mkdir()
    (templates / "t.launch.yaml.j2").write_text("launch:\n" + body)
    spec = tmp_path / "fleet.yaml"
    spec.write_text(
        "fleet: demo\nros: {use_sim_time: false}\ntemplates: templates\ndefaults: {template: t}\n"
        f"robots: [{robot}]\n"
    )
    return run_fleet(["render", str(spec), "-o", str(tmp_path / "out")]), templates / "t.launch.yaml.j2"


def refusal(capsys, code: int) -> str:
    stderr = capsys.readouterr().err
    assert code == 2 and "Traceback" not in stderr, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    return lines[0]


@pytest.mark.parametrize(
    "printed, number",
    [
        ("'nan'|float", "nan"),  # Jinja works these out while compiling: they crashed with NameError
        ("1e400", "inf"),
        ("-1e400", "-inf"),
        ("[1e400]", "inf"),  # in a list it was printed as JSON's Infinity, read back as text
    ],
)
def test_a_non_finite_number_printed_is_refused_at_its_line(tmp_path, capsys, printed, number):
    code, template = render_template(tmp_path, f"# {{{{ {printed} }}}}\n" + NAMESPACE)
    assert refusal(capsys, code) == f"fleet: error: {template}:2: cannot emit non-finite number {number}"


def test_a_non_finite_number_the_template_only_computes_with_renders(tmp_path):
    """A constant Jinja works out while compiling, used but not printed, is the number it is."""
    code, _ = render_template(
        tmp_path,
        "{% set x = 'inf'|float %}\n"
        "# {{ x > 1 }}\n"
        "- arg: {name: odd, default: {{ arg('odd', 'nan'|float) }}}\n" + NAMESPACE,
        robot="{name: r1, launch_args: {odd: 2.5}}",
    )
    assert code == 0
    text = (tmp_path / "out" / "r1" / "r1.launch.yaml").read_text()
    assert "# true\n" in text and '- arg: {name: odd, default: "2.5"}' in text


def test_an_unexpected_failure_of_jinja_is_the_templates_one_line(tmp_path, capsys):
    """Jinja's truncate asserts its length (an AssertionError, no kind of error fleet expected)."""
    code, template = render_template(tmp_path, NAMESPACE + "# {{ 'abc'|truncate(1) }}\n")
    assert refusal(capsys, code) == (
        f"fleet: error: {template}:4: template could not be rendered: AssertionError: expected length >= 3, got 1"
    )


def test_arg_called_wrongly_is_named_as_the_template_knows_it(tmp_path, capsys):
    code, template = render_template(tmp_path, "- arg: {name: speed, default: {{ arg('speed') }}}\n")
    assert refusal(capsys, code) == (
        f"fleet: error: {template}:2: arg() missing 1 required positional argument: 'default'"
    )


@pytest.mark.parametrize(
    "files, place",
    [
        ({"t.launch.yaml.j2": b"launch:\n# caf\xe9\n"}, "t.launch.yaml.j2:2"),
        ({"t.launch.yaml.j2": b"launch:\n{% include 'part.j2' %}\n", "part.j2": b"# one\n# caf\xe9\n"}, "part.j2:2"),
    ],
)
def test_a_template_file_that_is_not_utf8_is_refused_at_its_line_as_any_input_file(tmp_path, capsys, files, place):
    """The template, or a file it includes: named as fleet names any input it cannot read."""
    code, template = render_template(tmp_path, NAMESPACE)
    capsys.readouterr()
    for name, content in files.items():
        template.with_name(name).write_bytes(content)
    code = run_fleet(["render", str(tmp_path / "fleet.yaml")])
    assert refusal(capsys, code) == (
        f"fleet: error: {template.parent / place}: cannot read template file: not UTF-8 text (byte 0xe9)"
    )
