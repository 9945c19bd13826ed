"""Terminal output shared by all commands: error lines, JSON, rich consoles."""

from __future__ import annotations

import json
import sys
from typing import Any

from fleet.errors import FleetError


def print_error(error: FleetError | str) -> None:
    """One line on stderr: `fleet: error: <file:line:col>: <problem>`."""
    sys.stderr.write(f"fleet: error: {error}\n")
    sys.stderr.flush()


def print_json(data: Any) -> None:
    sys.stdout.write(json.dumps(data, indent=2, sort_keys=False, default=str) + "\n")


def console(stderr: bool = False):
    from rich.console import Console

    # soft_wrap: long messages (paths) stay on one line instead of being broken mid-word.
    return Console(stderr=stderr, highlight=False, soft_wrap=True)
