"""A test process killed outright (SIGKILL from the OOM killer or a CI runner, SIGTERM from an
IDE's stop button) takes its whole fleet with it: no router, agent, node, world or discovery
server may outlive it and keep the ROS domain whose lock the dead process released."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import psutil
import pytest

from fleet.testing.poll import poll
from fleet.testing.processes import MARKER_VARIABLE, processes_marked, terminate
from tests.e2e.e2e_helpers import TWO_ROBOTS

pytestmark = pytest.mark.integration

# Brings a fleet up, prints its marker and the pids of its processes, then waits to be killed.
HOLDER = textwrap.dedent(
    """
    import sys, time
    from fleet.testing import running_fleet
    from fleet.testing.processes import processes_marked

    with running_fleet(sys.argv[1], directory=sys.argv[2]) as fleet:
        print(fleet.marker, len(processes_marked(fleet.marker)), flush=True)
        time.sleep(600)
    """
)


@pytest.mark.parametrize("signum", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_killed_test_process_leaves_no_fleet_process(tmp_path, signum):
    env = {k: v for k, v in os.environ.items() if k != MARKER_VARIABLE}
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(TWO_ROBOTS), str(tmp_path / "fleet")],
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        env=env,
        text=True,
    )
    marker = ""
    try:
        assert holder.stdout is not None
        line = holder.stdout.readline().split()
        assert len(line) == 2, f"the fleet did not come up (exit {holder.poll()})"
        marker, count = line[0], int(line[1])
        assert count >= 5  # router, agent, nodes, world, discovery server
        holder.send_signal(signum)
        holder.wait(timeout=10)
        poll(
            lambda: processes_marked(marker),
            timeout=5,
            what="every process of the killed test's fleet to end",
            until=lambda alive: not alive,
            describe=lambda alive: "still alive: " + "; ".join(_command(p) for p in alive),
        )
    finally:
        if holder.poll() is None:
            holder.kill()
            holder.wait()
        if marker:
            terminate(processes_marked(marker))  # whatever this test found alive, it cleans up


def _command(process) -> str:
    try:
        return " ".join(process.cmdline())[:120]
    except psutil.Error:
        return f"pid {process.pid}"
