"""The checkout under test: where its example fleets are, and its `fleet` command run in this
process."""

from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
FLEETS = REPO / "fleets"


def run_fleet(args: list[str]) -> int:
    """Run the `fleet` command in this process; returns its exit code."""
    from fleet.cli import main

    try:
        main(args)
    except SystemExit as done:
        return int(done.code or 0)
    return 0
