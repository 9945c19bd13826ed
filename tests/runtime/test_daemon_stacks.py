"""A daemon that does not stop can be read before it is killed: SIGUSR1 makes it write every
thread's stack to its log (fleet.runtime.processes.stop_on_signals), and it keeps running."""

from __future__ import annotations

import subprocess
import sys
import time

from fleet.runtime.processes import STACKS_SIGNAL

DAEMON = """
import sys
from fleet.runtime.processes import stop_on_signals
stop = stop_on_signals()
print("ready", flush=True)
def stuck_somewhere():
    stop.wait()
stuck_somewhere()
print("stopped", flush=True)
"""


def test_a_daemon_writes_its_stacks_when_asked_and_runs_on(tmp_path):
    log = tmp_path / "daemon.log"
    with open(log, "wb") as output:
        daemon = subprocess.Popen([sys.executable, "-c", DAEMON], stdout=output, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 30
        while "ready" not in log.read_text() and time.monotonic() < deadline:
            time.sleep(0.05)
        daemon.send_signal(STACKS_SIGNAL)
        while "stuck_somewhere" not in log.read_text() and time.monotonic() < deadline:
            time.sleep(0.05)
        assert "stuck_somewhere" in log.read_text(), log.read_text()
        assert daemon.poll() is None  # still running
        daemon.terminate()
        assert daemon.wait(timeout=30) == 0
        assert log.read_text().endswith("stopped\n")
    finally:
        if daemon.poll() is None:
            daemon.kill()
            daemon.wait()
