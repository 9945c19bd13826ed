"""User-facing errors.

Every error a user can fix (bad spec, bad template, bad --set, bad launch file) is a FleetError
carrying where it happened.  The CLI prints it as one line, `file:line:col: message`, and exits 2.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

EXIT_USAGE = 2  # bad input: nothing was done
EXIT_FAILURE = 1  # the command ran but the fleet is not in the desired state


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
        if self.location is None:
            return self.message
        return f"{self.location}: {self.message}"


class SpecError(FleetError):
    """The fleet spec (or a --set override) is invalid."""


class TemplateError(FleetError):
    """A launch template is missing, malformed, or uses an undefined variable."""


class LaunchFileError(FleetError):
    """A launch description uses something the embedded runner cannot run."""


class ControlError(FleetError):
    """A control-plane request failed (agent unreachable, refused, timed out)."""

    exit_code = EXIT_FAILURE
