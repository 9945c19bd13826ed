"""Waiting in tests: look at something until it holds, or fail naming what was awaited and what
was seen last.  Every wait of fleet.testing and of the project's tests goes through poll()."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")


class WaitTimeout(AssertionError):
    """What a test waited for did not happen in time."""


def poll(
    observe: Callable[[], T],
    *,
    timeout: float,
    what: str,
    until: Callable[[T], Any] | None = None,
    interval: float = 0.1,
    pause: Callable[[float], Any] = time.sleep,
    retry_on: tuple[type[Exception], ...] = (),
    give_up_on: tuple[type[Exception], ...] = (),
    expired: Callable[[], bool] | None = None,
    explain: Callable[[], str] | None = None,
    describe: Callable[[Any], str] = repr,
) -> T:
    """Call observe() until its value is truthy (with `until`: until until(value) is), and
    return that value.

    Between looks, pause(interval) (time.sleep, or spinning an executor so that messages keep
    arriving).  An exception of a type in `retry_on` counts as "not yet", unless it is of a type
    in `give_up_on` (one no waiting cures): that one is raised at once.  After `timeout`
    seconds of wall time, or once expired() says another limit ran out (simulated time, say),
    raise WaitTimeout naming `what`, the time waited, the last value seen (as describe(value)
    shows it), the last exception and explain()."""
    __tracebackhide__ = True  # pytest shows the waiting test's line, not this loop
    started = time.monotonic()
    while True:
        value: Any = None
        error: Exception | None = None
        try:
            value = observe()
        except retry_on as raised:
            if isinstance(raised, give_up_on):
                raise
            error = raised
        if error is None and (until(value) if until is not None else value):
            return value
        waited = time.monotonic() - started
        if waited >= timeout or (expired is not None and expired()):
            message = (
                f"timed out waiting for {what}: {waited:.1f} s of wall time (limit {timeout:g}) passed; "
                f"last value: {describe(value)}"
            )
            if error is not None:
                message += f"; last error: {type(error).__name__}: {error}"
            if explain is not None:
                message += f"; {explain()}"
            raise WaitTimeout(message)
        pause(interval)
