"""User-facing errors.

Every error a user can fix (bad spec, bad template, bad --set, bad launch file) is a FleetError
carrying where it happened.  The CLI prints it as one line, `fleet: error: file:line:col: message`,
and exits 2.  The line is made here and nowhere else (`FleetError.line`): whatever a message
quotes from the input, it stays one line of at most MAX_LINE characters with no control
characters, so a hostile spec can neither forge a second error line nor drive the terminal.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

EXIT_USAGE = 2  # bad input: nothing was done
EXIT_FAILURE = 1  # the command ran but the fleet is not in the desired state

PREFIX = "fleet: error: "
MAX_LINE = 300  # characters of a whole error line, prefix included
COMMAND_LINE = "<command line>"  # the place of an error in the command's own arguments
_LONG_WORD = re.compile(r"\S{41,}")
_ESCAPES = {"\n": "\\n", "\r": "\\r", "\t": "\\t"}


def did_you_mean(name: str, names: Iterable[str]) -> str:
    """The hint an error about a name that is not there gives: ` (did you mean 'closest'?)`, or
    "" when no name is close."""
    guess = difflib.get_close_matches(name, sorted(names), n=1)
    return f" (did you mean {guess[0]!r}?)" if guess else ""


def printable(text: str) -> str:
    """`text` with every non-printable character (newlines, ESC, NUL, bidi controls, ...) escaped."""
    if text.isprintable():
        return text
    return "".join(char if char.isprintable() else _escape(char) for char in text)


def _escape(char: str) -> str:
    if char in _ESCAPES:
        return _ESCAPES[char]
    code = ord(char)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def one_line(text: str, limit: int = MAX_LINE) -> str:
    """`text` made printable and at most `limit` characters: the longest values are shortened
    first, keeping their two ends; if that is not enough, the middle of the text goes."""
    text = printable(text)
    if len(text) <= limit:
        return text
    for word in sorted(set(_LONG_WORD.findall(text)), key=len, reverse=True):
        text = text.replace(word, f"{word[:18]}...{word[-18:]}")
        if len(text) <= limit:
            return text
    head = (limit - 5) * 2 // 3
    return f"{text[:head]} ... {text[len(text) - (limit - 5 - head) :]}"


PYDANTIC_PREFIX = "Value error, "  # what pydantic puts before a validator's own words


def validation_message(problem: Mapping[str, Any]) -> str:
    """The message of one problem pydantic found (an item of ValidationError.errors()), in the
    validator's own words."""
    return str(problem["msg"]).removeprefix(PYDANTIC_PREFIX)


def error_line(problem: str) -> str:
    """`fleet: error: <problem>` as one printable line of at most MAX_LINE characters."""
    return PREFIX + one_line(problem, MAX_LINE - len(PREFIX))


def relative_to_cwd(path: Path) -> Path:
    """`path` relative to the working directory when it lies inside it, else as it is: files fleet
    finds itself (the built-in templates) are named in messages as a compiler names the files it
    found, `templates/diff_drive.params.yaml:7:14` from the checkout."""
    try:
        return path.relative_to(Path.cwd()) if path.is_absolute() else path
    except (ValueError, OSError):  # outside it, or the working directory is gone
        return path


@dataclass
class Location:
    file: str | Path | None = None
    line: int | None = None  # 1-based
    column: int | None = None  # 1-based

    def __str__(self) -> str:
        parts = [str(self.file) if self.file is not None else "<input>"]
        if self.line is not None:
            parts.append(str(self.line))
            if self.column is not None:
                parts.append(str(self.column))
        return ":".join(parts)


class FleetError(Exception):
    """An error in the user's input, reported as one line with its location."""

    exit_code = EXIT_USAGE

    def __init__(self, message: str, location: Location | None = None):
        super().__init__(message)
        self.message = message
        self.location = location

    def __str__(self) -> str:
        limit = MAX_LINE - len(PREFIX)
        if self.location is None:
            return one_line(self.message, limit)
        where = one_line(str(self.location), limit // 2)  # the place stays readable, whatever the message
        return f"{where}: {one_line(self.message, limit - len(where) - 2)}"

    def line(self) -> str:
        """The one line the CLI prints.  Bad input without a file is in the command's arguments."""
        if self.location is None and self.exit_code == EXIT_USAGE:
            return error_line(f"{COMMAND_LINE}: {self.message}")
        return PREFIX + str(self)


class SpecError(FleetError):
    """The fleet spec (or a --set override) is invalid."""


class TemplateError(FleetError):
    """A launch template is missing, malformed, or uses an undefined variable."""


class LaunchFileError(FleetError):
    """A launch description uses something the embedded runner cannot run."""


class NeedsRos2Launch(LaunchFileError):
    """A launch file `ros2 launch` would run, and the embedded runner does not (a Python launch
    file, an action, attribute or substitution it leaves to the ros2 backend)."""


class ControlError(FleetError):
    """A control-plane request failed (agent unreachable, refused, timed out)."""

    exit_code = EXIT_FAILURE


class RouterSilent(ControlError):
    """The router did not answer at all, even after waiting for it (a denial ends at once)."""


class BadRequest(ControlError):
    """The fleet refused a request for what the command named (a robot or node it does not have, a
    name it cannot take): the user's input is wrong, so it is bad input (exit 2), found out by asking."""

    exit_code = EXIT_USAGE
