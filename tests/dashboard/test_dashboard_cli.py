"""`fleet dashboard`'s bad input: a port in use is one line and exit 2, before anything else."""

from __future__ import annotations

import socket
import subprocess
import sys


def test_port_in_use_is_one_line_and_exit_2():
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        # No router runs at this endpoint: the port is checked first, so the error is about it.
        result = subprocess.run(
            [sys.executable, "-m", "fleet", "dashboard", "--port", str(port), "--connect", "tcp/127.0.0.1:1"],
            capture_output=True,
            text=True,
            timeout=60,
        )
    assert result.returncode == 2, result
    assert result.stderr.splitlines() == [
        f"fleet: error: <command line>: dashboard: port {port} on 127.0.0.1 is in use (another program listens there): "
        "pick another with --port, or --port 0 for a free one"
    ]
    assert result.stdout == ""


def test_unreachable_router_is_one_line():
    result = subprocess.run(
        [sys.executable, "-m", "fleet", "dashboard", "--port", "0", "--connect", "tcp/127.0.0.1:1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode == 1, result
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert result.stderr.startswith("fleet: error: cannot reach the fleet router at tcp/127.0.0.1:1")
    assert "on this computer `fleet up` starts it, as `fleet deploy` does" in result.stderr  # a loopback router
