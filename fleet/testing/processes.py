"""Finding and stopping the processes a test (or a fleet) started.

Every process started during a test inherits an environment marker; after the test, whatever
still carries the marker is killed, daemons that left our process tree included.
"""

from __future__ import annotations

import psutil

from fleet.runtime import processes
from fleet.runtime.processes import terminate

__all__ = ["MARKER_VARIABLE", "processes_marked", "terminate"]

MARKER_VARIABLE = "FLEET_TEST_ID"


def processes_marked(value: str, variable: str = MARKER_VARIABLE) -> list[psutil.Process]:
    """Live processes (other than this one) whose environment has variable=value."""
    return processes.processes_marked(value, variable)
