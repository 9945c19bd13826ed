"""Zenoh's threads in fleet's processes: a bridge's session reads its link on Zenoh's application
thread (fleet.dataplane.bridge.ZENOH_RUNTIME) without leaving the setting to the processes it
would start; the router keeps Zenoh's own threads for reading its many links; a user's own
ZENOH_RUNTIME wins."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from tests.control.control_helpers import thread_names, zenoh_runtimes

pytestmark = pytest.mark.integration

# Opens a client session as a bridge does, to the router at argv[1], and asks the router's
# registry for its status: once the answer is in, this process has read its link, and so has the
# router.  Then prints its threads' names and whether ZENOH_RUNTIME is left in its environment
# (what a process it started would inherit).
CLIENT = """
import json, os, sys
from pathlib import Path
from fleet.dataplane.bridge import ZENOH_RUNTIME
from fleet.wire.protocol import status_query
from fleet.wire.session import open_client
session = open_client([sys.argv[1]], runtime=ZENOH_RUNTIME)
answers = [reply for reply in session.get(status_query("probe"), timeout=30) if reply.ok is not None]
names = sorted(Path(task, "comm").read_text().strip() for task in Path("/proc/self/task").iterdir())
print(json.dumps({"answers": len(answers), "threads": names, "left": os.environ.get("ZENOH_RUNTIME")}))
session.close()
"""


def client(endpoint: str, **env: str) -> dict:
    environment = {key: value for key, value in os.environ.items() if key != "ZENOH_RUNTIME"} | env
    out = subprocess.run(
        [sys.executable, "-c", CLIENT, endpoint], env=environment, capture_output=True, text=True, timeout=60
    )
    assert out.returncode == 0, out.stderr
    seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert seen["answers"] >= 1, seen  # the router's registry answered: both sides read the link
    return seen


def test_a_bridge_reads_its_link_on_the_application_thread_and_the_router_on_its_own(fresh_cluster):
    fresh_cluster.start_router()
    seen = client(fresh_cluster.endpoint)
    assert "app" in zenoh_runtimes(seen["threads"]) and "rx" not in zenoh_runtimes(seen["threads"]), seen
    assert seen["left"] is None  # not inherited by what the process starts
    router = fresh_cluster.pid("router")
    assert router is not None  # it has read this client's link: it answered the query
    assert "rx" in zenoh_runtimes(thread_names(router))


def test_a_users_own_zenoh_runtime_wins(fresh_cluster):
    fresh_cluster.start_router()
    seen = client(fresh_cluster.endpoint, ZENOH_RUNTIME="(rx: (worker_threads: 1))")
    assert "rx" in zenoh_runtimes(seen["threads"]), seen
    assert seen["left"] == "(rx: (worker_threads: 1))"
