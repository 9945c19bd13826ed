"""Substitutions in launch attribute text: `$(var X)`, `$(env X DEFAULT)`, `$(find-pkg-share P)`...

Parsed as launch's frontend grammar reads them: a substitution's arguments are separated by
whitespace, may be quoted, and may themselves hold substitutions.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Subst:
    kind: str
    args: tuple[Text, ...]


Text = tuple["str | Subst", ...]

# What the embedded runner evaluates, with the number of arguments each takes.
ARITY = {
    "var": (1, 1),
    "env": (1, 2),
    "dirname": (0, 0),
    "filename": (0, 0),
    "find-pkg-share": (1, 1),
    "find-pkg-prefix": (1, 1),
    "exec-in-pkg": (2, 2),
    "not": (1, 1),
    "and": (2, 2),
    "or": (2, 2),
    "equals": (1, 2),
    "not-equals": (1, 2),
}
# What launch also knows: refused here, with a pointer to the ros2 backend.
ROS2_ONLY = {
    "anon",
    "any",
    "all",
    "command",
    "eval",
    "file-content",
    "find-exec",
    "if",
    "launch_log_dir",
    "log_dir",
    "param",
}


class SubstitutionSyntax(Exception):
    """Why a text cannot be read; `offset` is where in the text (0-based)."""

    def __init__(self, message: str, offset: int):
        super().__init__(message)
        self.offset = offset


class Ros2OnlySubstitution(SubstitutionSyntax):
    """A substitution of ROS2_ONLY: `ros2 launch` would read the text."""


_NAME = re.compile(r"\s*([A-Za-z][A-Za-z0-9_-]*)")


def _parse_parts(text: str, start: int, inside: bool) -> tuple[list[Any], int]:
    parts: list[Any] = []
    literal: list[str] = []
    index = start
    quote: str | None = None
    while index < len(text):
        char = text[index]
        if text.startswith("$(", index):
            if literal:
                parts.append("".join(literal))
                literal = []
            subst, index = _parse_subst(text, index + 2)
            parts.append(subst)
            continue
        if inside:
            if quote is not None:
                if char == quote:
                    quote = None
                    index += 1
                    continue
            elif char in "'\"":
                quote = char
                index += 1
                continue
            elif char.isspace() or char == ")":
                break
        literal.append(char)
        index += 1
    if quote is not None:
        raise SubstitutionSyntax(f"unterminated quote in {text!r}", start)
    if literal:
        parts.append("".join(literal))
    return parts, index


def _parse_subst(text: str, index: int) -> tuple[Subst, int]:
    begin = index - 2
    match = _NAME.match(text, index)
    if match is None:
        raise SubstitutionSyntax(f"substitution without a name in {text!r}", begin)
    kind = match.group(1)
    index = match.end()
    args = []
    while True:
        while index < len(text) and text[index].isspace():
            index += 1
        if index >= len(text):
            raise SubstitutionSyntax(f"unterminated substitution '$({kind}' in {text!r}", begin)
        if text[index] == ")":
            index += 1
            break
        arg, index = _parse_parts(text, index, inside=True)
        args.append(tuple(arg))
    if kind in ROS2_ONLY:
        raise Ros2OnlySubstitution(
            f"substitution '$({kind})' is not run by the embedded runner; it needs the ros2 backend (--backend ros2)",
            begin,
        )
    if kind not in ARITY:
        raise SubstitutionSyntax(f"unknown substitution '$({kind})'", begin)
    low, high = ARITY[kind]
    if not low <= len(args) <= high:
        raise SubstitutionSyntax(f"'$({kind})' takes {low}..{high} arguments, got {len(args)}", begin)
    return Subst(kind, tuple(args)), index


def parse_substitutions(text: str) -> tuple[Any, ...]:  # Text; Any: callers look into its parts
    parts, _ = _parse_parts(text, 0, inside=False)
    return tuple(parts)


def literal(text: Text) -> str | None:
    """The text when it holds no substitution, else None."""
    if all(isinstance(part, str) for part in text):
        return "".join(text)  # type: ignore[arg-type]
    return None


def written(text: Text) -> str:
    """Substitution text as it would be written (for --show-args and messages)."""
    out = []
    for part in text:
        if isinstance(part, str):
            out.append(part)
        else:
            out.append("$(" + " ".join([part.kind, *(written(arg) for arg in part.args)]) + ")")
    return "".join(out)


@functools.lru_cache(maxsize=4096)  # a fleet's robots pass the same arguments, mostly
def split_command_line(parts: Text) -> tuple[Text, ...]:
    """The arguments of `args`/`ros_args`/`cmd` text, each a Text, split as launch's
    ExecuteProcess._parse_cmdline does: literal text on (shell-quoted) whitespace, a
    substitution one piece glued to the text it touches.  Its quirks are kept: text of only
    whitespace ends the argument being built even when there is none, so `args: '   '` passes one
    empty argument, and so does `$(var a)  $(var b)`.  The one splitter of the embedded runner
    and of the generated Python launch file.  Raises ValueError for unbalanced quotes."""
    import shlex

    arguments: list[Text] = []
    current: list[str | Subst] = []

    def end() -> None:
        nonlocal current
        arguments.append(tuple(current))
        current = []

    for part in parts:
        if isinstance(part, Subst):
            current.append(part)
            continue
        tokens = shlex.split(part)
        if not tokens:
            end()
            continue
        if part[0].isspace() and current:
            end()
        current.append(tokens[0])
        if len(tokens) > 1:
            end()
            current.append(tokens[-1])
        if len(tokens) > 2:
            arguments.extend((token,) for token in tokens[1:-1])
        if part[-1].isspace():
            end()
    if current:
        arguments.append(tuple(current))
    return tuple(arguments)
