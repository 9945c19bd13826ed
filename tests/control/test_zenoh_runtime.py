"""fleet's Zenoh processes do their link I/O on Zenoh's application threads (fleet.wire.session,
RUNTIME): one thread wake-up fewer per message on each side of a hop."""

from __future__ import annotations

from pathlib import Path

import pytest

from fleet.testing.control_plane import ROUTER

pytestmark = pytest.mark.integration


def thread_names(pid: int) -> list[str]:
    return [task.joinpath("comm").read_text().strip() for task in Path(f"/proc/{pid}/task").iterdir()]


def test_the_router_serves_its_links_from_zenoh_s_application_threads(fresh_cluster):
    fresh_cluster.start_router()
    pid = fresh_cluster.pid(ROUTER)
    assert pid is not None
    with fresh_cluster.client():  # a link open on both sides
        names = thread_names(pid)
    assert any(name.startswith("app-") for name in names), names
    # Zenoh's own runtimes for receiving, sending and accepting would each have threads of their own.
    assert not [name for name in names if name.split("-")[0] in ("rx", "tx", "acc")], names
