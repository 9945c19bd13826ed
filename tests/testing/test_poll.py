"""fleet.testing.poll: what a wait returns, and what its failure says."""

from __future__ import annotations

import itertools

import pytest

from fleet.testing.poll import WaitTimeout, poll


def test_returns_the_first_value_that_holds():
    counter = itertools.count()
    assert poll(lambda: next(counter), until=lambda n: n >= 3, timeout=5, interval=0, what="3") == 3
    assert poll(lambda: [1], timeout=5, what="a list") == [1]


def test_failure_names_what_was_awaited_and_the_last_value():
    counter = itertools.count()
    with pytest.raises(WaitTimeout) as failure:
        poll(
            lambda: next(counter),
            until=lambda n: n < 0,
            timeout=0.2,
            interval=0.01,
            what="a negative count",
            describe=lambda n: f"count {n}",
            explain=lambda: "counted from 0",
        )
    message = str(failure.value)
    assert isinstance(failure.value, AssertionError)
    assert message.startswith("timed out waiting for a negative count: ")
    assert "(limit 0.2)" in message and message.endswith("; counted from 0")
    last = int(message.split("last value: count ")[1].split(";")[0])
    assert last == next(counter) - 1  # the very last look


def test_retried_exceptions_are_shown_and_others_raised():
    def missing():
        raise KeyError("robot1")

    with pytest.raises(WaitTimeout, match="last error: KeyError: 'robot1'"):
        poll(missing, timeout=0.1, interval=0.01, what="robot1", retry_on=(KeyError,))
    with pytest.raises(KeyError):
        poll(missing, timeout=5, what="robot1")


def test_another_limit_ends_the_wait_before_the_wall_time():
    looks = itertools.count(1)
    with pytest.raises(WaitTimeout):
        poll(lambda: False, timeout=60, interval=0, what="never", expired=lambda: next(looks) >= 3)
    assert next(looks) == 4  # stopped at the third look, not after 60 s
