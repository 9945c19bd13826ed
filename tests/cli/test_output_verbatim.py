"""What the CLI prints shows users' values as they are: rich reads `[front, back]` as a style tag
(and drops it) and `base:robot:link` as an emoji code unless its markup and emoji are off."""

from __future__ import annotations

import pytest

from fleet.cli import main
from fleet.cli.output import console
from fleet.cli.status_view import print_view
from fleet.plan.view import AgentRow, FleetView, RobotRow
from tests.checkout import FLEETS

TWO_ROBOTS = FLEETS / "two_robots.yaml"
LIST_OF_WORDS = "[front, back]"  # a string list parameter as the tables format it
COLONS = "base:robot:link"  # ":robot:" is rich's emoji code for a robot face


def run_cli(args: list[str], capsys) -> tuple[int, str, str]:
    """Exit code, stdout and stderr of a fleet command."""
    with pytest.raises(SystemExit) as exited:
        main(args)
    captured = capsys.readouterr()
    return int(exited.value.code or 0), captured.out, captured.err


def test_render_shows_parameter_values_and_warnings_verbatim(capsys):
    sets = ["--set", f"robot1.controller.frame_names={LIST_OF_WORDS}", "--set", f"robot1.controller.frame_id={COLONS}"]
    code, out, err = run_cli(["render", str(TWO_ROBOTS), *sets], capsys)
    assert code == 0
    rows = {line.split()[2]: line for line in out.splitlines() if line.startswith("robot1 ")}
    assert LIST_OF_WORDS in rows["frame_names"]
    assert COLONS in rows["frame_id"]
    assert "warning:" not in out  # the report is on stdout, its warnings on stderr (as deploy's)
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert any(f"frame_names={LIST_OF_WORDS}:" in line for line in warnings), warnings
    assert any(f"frame_id={COLONS}:" in line for line in warnings), warnings
    assert "\N{ROBOT FACE}" not in out


def test_a_warning_quoting_a_newline_stays_one_line(capsys):
    code, _, err = run_cli(["render", str(TWO_ROBOTS), "--set", "robot1.controller.new_one=a\nb\rc"], capsys)
    assert code == 0
    (warning,) = [line for line in err.splitlines() if "new_one" in line]
    assert warning.startswith("warning: ") and "new_one=a\\nb\\rc:" in warning, err


def test_explain_shows_the_value_verbatim(capsys):
    sets = ["--set", f"robot1.controller.frame_names={LIST_OF_WORDS}"]
    code, out, _ = run_cli(["render", str(TWO_ROBOTS), *sets, "--explain", "robot1.controller.frame_names"], capsys)
    assert code == 0
    assert f"robot1.controller.frame_names = {LIST_OF_WORDS}" in out


def test_status_shows_reasons_and_errors_verbatim(capsys):
    agent = AgentRow(name="rack", online=True, last_seen=None, hostname="rack-1", address="10.0.0.2", fleets=["f"])
    robots = [
        RobotRow(
            fleet="f", name="r1", kind="robot", agent="rack", state="degraded", reason=f"[scan] silent on {COLONS}"
        ),
        RobotRow(fleet="f", name="r2", kind="robot", agent="rack", state="failed", error="[Errno 2] no such file: [a]"),
    ]
    print_view(FleetView(agents=[agent], robots=robots), console())
    out = capsys.readouterr().out
    assert f"[scan] silent on {COLONS}" in out
    assert "f/r2 on rack: [Errno 2] no such file: [a]" in out
    assert "online" in out and "degraded" in out
