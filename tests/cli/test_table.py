"""The CLI's tables (fleet.cli.table) as a user's screen shows them: aligned columns, colours on
the right words, the last column wrapped on a narrow screen and nothing else cut, a thousand
rows laid out in one go."""

from __future__ import annotations

import io
import re

from rich.console import Console
from rich.text import Text

from fleet.cli.output import table

ANSI = re.compile(r"\x1b\[[0-9;]*m")
REASON = "no cmd_vel from it has reached the world for 7 s"


def screen(renderable, width: int, colour: bool = False, terminal: bool = True) -> list[str]:
    """What a terminal `width` columns wide shows, line by line (as fleet's consoles are set up);
    terminal=False: what a pipe of a console that width gets."""
    out = io.StringIO()
    console = Console(
        file=out, width=width, force_terminal=terminal, color_system="standard" if colour else None, soft_wrap=True
    )
    console.print(renderable)
    return out.getvalue().splitlines()


def robots_table():
    rows = table("robot", "agent", "state", "reason", title="Robots")
    rows.add_row("robot1", "rack_a", Text("running", style="green"), "")
    rows.add_row("robot2", "rack_b", Text.assemble(("degraded", "yellow"), " (live overrides)"), REASON)
    return rows


def test_columns_line_up_under_upper_case_headers_and_a_rule():
    lines = screen(robots_table(), 200)
    assert lines[0] == "Robots"
    assert lines[1] == "ROBOT    AGENT    STATE                       REASON"
    assert lines[2] == "\u2500" * len(lines[4])
    assert lines[3] == "robot1   rack_a   running"
    assert lines[4] == f"robot2   rack_b   degraded (live overrides)   {REASON}"
    assert all(line == line.rstrip() for line in lines)


def test_colours_fall_on_the_words_they_belong_to():
    lines = screen(robots_table(), 200, colour=True)
    assert "\x1b[32mrunning\x1b[0m" in lines[3]
    assert "\x1b[33mdegraded\x1b[0m (live overrides)" in lines[4]
    assert [ANSI.sub("", line) for line in lines] == screen(robots_table(), 200)


def test_a_table_a_little_too_wide_closes_its_columns_up_to_two_spaces():
    wide = screen(robots_table(), 200)
    lines = screen(robots_table(), len(wide[4]) - 1)
    assert lines[4] == f"robot2  rack_b  degraded (live overrides)  {REASON}"
    assert lines[2] == "\u2500" * len(lines[4])


def test_on_a_narrow_screen_only_the_last_column_wraps_within_its_column():
    lines = screen(robots_table(), 72)
    start = lines[1].index("REASON")
    assert lines[3] == "robot1  rack_a  running"
    assert lines[4].startswith("robot2  rack_b  degraded (live overrides)  no cmd_vel")
    continued = lines[5:]
    assert continued and all(line[:start].strip() == "" for line in continued)
    assert " ".join(line.strip() for line in [lines[4][start:], *continued]) == REASON
    assert all(len(line) <= 72 for line in lines)


def test_a_screen_too_narrow_for_the_last_column_leaves_lines_long_rather_than_cutting_words():
    lines = screen(robots_table(), 40)
    assert lines[4] == f"robot2  rack_b  degraded (live overrides)  {REASON}"
    assert len(lines) == 5


def test_into_a_pipe_a_row_stays_one_line_for_grep():
    lines = screen(robots_table(), 40, terminal=False)
    assert lines[4] == f"robot2   rack_b   degraded (live overrides)   {REASON}"
    assert len(lines) == 5


def test_a_cell_of_several_lines_keeps_its_row_and_its_column():
    rows = table("parameter", "value", "from")
    rows.add_row("frames", "- front\n- back", "spec")
    rows.add_row("rate", "10", "template")
    lines = screen(rows, 200)
    column = lines[0].index("VALUE")
    assert lines[2].startswith("frames") and lines[2][column:].split() == ["-", "front", "spec"]
    assert lines[3][:column].strip() == "" and lines[3][column:] == "- back"
    assert lines[4].split() == ["rate", "10", "template"]


def test_wide_characters_and_control_codes_do_not_shift_the_columns():
    rows = table("name", "note")
    rows.add_row("\u30ed\u30dc\u30c3\u30c8", "wide")  # ロボット: 4 characters, 8 cells
    rows.add_row("bad\rname", "carriage return")
    rows.add_row("robot", Text("ok\r", style="green"))
    lines = screen(rows, 200)
    assert lines[2] == "\u30ed\u30dc\u30c3\u30c8   wide"
    assert lines[3] == "badname    carriage return"
    assert lines[4] == "robot      ok"


def test_a_short_row_is_filled_with_blank_cells():
    rows = table("robot", "state", "reason")
    rows.add_row("robot1", "running")
    rows.add_row("robot2", "degraded", "no /clock")
    assert screen(rows, 80)[2:] == ["robot1   running", "robot2   degraded   no /clock"]


def test_an_empty_table_shows_its_headers():
    assert screen(table("robot", "state"), 80) == ["ROBOT   STATE", "\u2500" * 13]


def test_a_thousand_rows_make_one_line_each():
    rows = table("robot", "state")
    for i in range(1000):
        rows.add_row(f"robot{i}", Text("running", style="green"))
    lines = screen(rows, 80)
    assert len(lines) == 1002
    assert lines[-1] == "robot999   running"


def test_a_row_style_lies_under_its_cells_own_colours():
    rows = table("layer", "state")
    rows.add_row("spec", Text("effective", style="green"), style="bold")
    rows.add_row("template", "overridden", style="dim")
    lines = screen(rows, 80, colour=True)
    assert lines[2] == "\x1b[1mspec       \x1b[0m\x1b[1;32meffective\x1b[0m"
    assert lines[3] == "\x1b[2mtemplate   overridden\x1b[0m"
