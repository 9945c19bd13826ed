"""pytest plugin for multi-robot integration tests (registered as the `fleet` pytest11 entry point,
so installing fleet is enough).

Fixtures:
- `fleet_up`: a factory; `fleet_up("fleets/two_robots.yaml", sets=[...])` brings a fleet up in
  this test's tmp_path, isolated from everything else on the machine, and returns its
  FleetHandle (fleet.testing.fleet_handle).  Every fleet it started is torn down after the test,
  also when it failed; a process that outlived the clean stop fails the test's teardown.
For a fleet shared by a module's tests, use fleet.testing.running_fleet in your own fixture.

When a test fails while a fleet is up, its report gets the status table, the last log lines of
each node, the world's state and the path of a snapshot picture of the world.
"""

from __future__ import annotations

import os
import re

import pytest

from fleet.testing.fleet_handle import OPEN_HANDLES, FleetHandle


def pytest_configure(config) -> None:
    # FastDDS reads its transport choice once per process: before any test creates a
    # participant, choose UDP so a killed test process leaves nothing in /dev/shm (as the
    # fleet's own processes do; see fleet.runtime.environment).
    os.environ.setdefault("FASTDDS_BUILTIN_TRANSPORTS", "UDPv4")
    config.addinivalue_line("markers", "fleet: a test that brings up a fleet with fleet.testing")


@pytest.fixture
def fleet_up(tmp_path):
    """Factory: fleet_up(spec, sets=(), timeout=120) -> a running FleetHandle (torn down after the test)."""
    handles: list[FleetHandle] = []

    def start(spec, sets=(), timeout: float = 120.0) -> FleetHandle:
        handle = FleetHandle(spec, tmp_path / f"fleet{len(handles)}", sets)
        handles.append(handle)
        handle.start(timeout)
        return handle

    yield start
    problems = []
    for handle in reversed(handles):
        try:
            handle.close()
        except AssertionError as leak:
            problems.append(str(leak))
    if problems:
        pytest.fail("\n".join(problems), pytrace=False)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    report = outcome.get_result()
    # "setup" too: a fixture of the user's that calls fleet_up and waits fails there
    if report.when not in ("setup", "call") or not report.failed:
        return
    for handle in list(OPEN_HANDLES):
        snapshot = handle.root / f"failure-{_file_name(item.name)}.png"
        try:
            sections = handle.failure_sections(snapshot)
        except Exception as error:  # never let the report replace the failure
            sections = [(f"fleet {handle.name}", f"(report unavailable: {error})")]
        for title, text in sections:
            report.sections.append((title, text))


def _file_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)[:80]
