"""Terminal output shared by all commands: error lines, JSON, rich consoles."""

from __future__ import annotations

import json
import sys
from typing import Any

from fleet.errors import FleetError, error_line


def print_error(error: FleetError | str) -> None:
    """One line on stderr: `fleet: error: <file:line:col>: <problem>` (see fleet.errors)."""
    sys.stderr.write((error.line() if isinstance(error, FleetError) else error_line(error)) + "\n")
    sys.stderr.flush()


def print_warnings(warnings: list[str]) -> None:
    """A spec's warnings, one `warning:` line each, on stderr: a command's output (a JSON
    document, a table) stays what it is on stdout, as kubectl's warnings do."""
    if warnings:
        from fleet.errors import printable

        errors = console(stderr=True)
        for warning in warnings:  # they quote the user's input, which may hold a newline or ESC
            errors.print(labelled("warning:", "yellow", printable(warning)))


def print_json(data: Any) -> None:
    sys.stdout.write(json_text(data) + "\n")


def print_json_line(data: Any) -> None:
    """One JSON document on one line, flushed at once: a stream of them (status --watch --json)
    is read line by line by the program at its other end."""
    sys.stdout.write(json.dumps(data, default=str) + "\n")
    sys.stdout.flush()


def json_text(data: Any, depth: int = 2, indent: str = "") -> str:
    """JSON indented down to `depth` levels, each deeper value on one line: a document of 10,000
    robots reads as one robot per line, and is written by json's C encoder (indenting every level
    takes its pure-Python one, six times slower)."""
    inner = indent + "  "
    if depth > 0 and isinstance(data, dict) and data:
        items = (f"{inner}{json.dumps(str(key))}: {json_text(value, depth - 1, inner)}" for key, value in data.items())
        return "{\n" + ",\n".join(items) + f"\n{indent}}}"
    if depth > 0 and isinstance(data, (list, tuple)) and data:
        items = (f"{inner}{json_text(value, depth - 1, inner)}" for value in data)
        return "[\n" + ",\n".join(items) + f"\n{indent}]"
    return json.dumps(data, default=str)


def console(stderr: bool = False):
    from rich.console import Console

    # soft_wrap: long messages (paths) stay on one line instead of being broken mid-word; tables
    # fit themselves to a terminal's width (fleet.cli.table), and into a pipe keep a row a line.
    # markup and emoji off: what is printed holds users' values (parameters, paths, reasons), and
    # rich would read `[front, back]` as a style tag and drop it, `base:robot:link` as an emoji
    # code. Styles are given as rich Text's (see `labelled`), never inside strings.
    return Console(stderr=stderr, highlight=False, soft_wrap=True, markup=False, emoji=False)


def labelled(label: str, style: str, text: str = ""):
    """`label` in `style`, then `text` as it is: "warning: ...", "note: ...", "fleet up"."""
    from rich.text import Text

    return Text.assemble((label, style), f" {text}" if text else "")


def table(*columns: str, title: str | None = None):
    """A kubectl-like table: upper-case headers over a rule, no borders (fleet.cli.table)."""
    from fleet.cli.table import Table

    return Table(columns, title)
