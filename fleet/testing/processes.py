"""Finding and stopping the processes a test (or a fleet) started.

Every process started during a test inherits an environment marker; after the test, whatever
still carries the marker is killed, daemons that left our process tree included.
"""

from __future__ import annotations

import contextlib
import os

import psutil

MARKER_VARIABLE = "FLEET_TEST_ID"


def processes_marked(value: str, variable: str = MARKER_VARIABLE) -> list[psutil.Process]:
    """Live processes (other than this one) whose environment has variable=value."""
    found = []
    me = os.getpid()
    for proc in psutil.process_iter(["pid"]):
        if proc.pid == me:
            continue
        try:
            if proc.environ().get(variable) == value and proc.status() != psutil.STATUS_ZOMBIE:
                found.append(proc)
        except (psutil.NoSuchProcess, psutil.AccessDenied, psutil.ZombieProcess):
            continue
    return found


def terminate(processes: list[psutil.Process], timeout: float = 5.0) -> None:
    """SIGTERM, wait, then SIGKILL whatever is left."""
    for proc in processes:
        with contextlib.suppress(psutil.NoSuchProcess):
            proc.terminate()
    _, alive = psutil.wait_procs(processes, timeout=timeout)
    for proc in alive:
        with contextlib.suppress(psutil.NoSuchProcess):
            proc.kill()
    psutil.wait_procs(alive, timeout=timeout)
