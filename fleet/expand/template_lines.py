"""Which line of a template wrote a line of its output, for errors found only in the output (a
rendered launch file that is not YAML, or that the launch reader refuses).  Jinja keeps no map
from output to source, so the output line is matched against the template's lines as patterns."""

from __future__ import annotations

import re
from pathlib import Path


def source_line_of(template_file: str | Path, output: str, line: int | None) -> int | None:
    """The line of `template_file` that wrote line `line` of its `output`, when one could have."""
    lines = output.splitlines()
    if line is None or not 1 <= line <= len(lines):
        return None
    try:
        source = Path(template_file).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    return output_line_source(lines[line - 1], source)


def output_line_source(output_line: str, source: str) -> int | None:
    """The line of a template's source that rendered `output_line` of its output, when exactly one
    line could have (its text, each `{{ }}` standing for any text, is the output line); None when
    none or several could.  Comments, whole lines of them included, render as nothing."""
    without_comments = re.sub(r"\{#.*?#\}", lambda comment: "\n" * comment.group().count("\n"), source, flags=re.S)
    found = [
        number
        for number, line in enumerate(without_comments.splitlines(), 1)
        if line.strip() and _line_pattern(line).fullmatch(output_line)
    ]
    return found[0] if len(found) == 1 else None


def _line_pattern(line: str) -> re.Pattern[str]:
    """A template line as a pattern of what it can print: a `{{ }}` any text, a `{% %}` nothing."""
    parts = re.split(r"(\{\{.*?\}\}|\{%.*?%\})", line)
    printed = {"{{": ".*", "{%": ""}
    return re.compile("".join(printed.get(part[:2], re.escape(part)) for part in parts))
