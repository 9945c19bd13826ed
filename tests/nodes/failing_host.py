"""A host process (fleet.nodes.host.main, unchanged) whose one robot fails once and is made again,
driven from a thread of its own over the host's control channel; it prints, as its last line, the
JSON list of the modules imported between the robot's running and its running again.

    python -m tests.nodes.failing_host SOCKET

Run in a process of its own: what a host imports is seen only in a fresh interpreter (a test's
has imported half of fleet already).
"""

from __future__ import annotations

import json
import os
import signal
import socket
import sys
import threading
import time

from fleet.nodes import host

ROBOT = "robot1"
NODES = [
    {"executable": "controller", "ros_args": ["--ros-args", "-r", f"__ns:=/{ROBOT}"], "logger": f"{ROBOT}.controller"},
    {"executable": "battery", "ros_args": ["--ros-args", "-r", f"__ns:=/{ROBOT}"], "logger": f"{ROBOT}.battery"},
]
SETTLE = 2.0  # s the robot runs before the snapshot: whatever its first callbacks import is in it
TIMEOUT = 30.0


def drive(control: str) -> None:
    try:
        with connect(control) as connection, connection.makefile("rwb") as stream:

            def call(request: dict) -> dict:
                stream.write(json.dumps(request).encode() + b"\n")
                stream.flush()
                return json.loads(stream.readline())

            def wait_running(restarts: int) -> None:
                deadline = time.monotonic() + TIMEOUT
                while time.monotonic() < deadline:
                    robot = call({"op": "status"})["robots"][ROBOT]
                    if robot["state"] == "running" and robot["restarts"] == restarts:
                        return
                    time.sleep(0.05)
                raise TimeoutError(f"{ROBOT} not running with {restarts} restarts: {robot}")

            assert call({"op": "add", "robot": ROBOT, "respawn_delay": 0.1, "nodes": NODES})["ok"]
            wait_running(0)
            time.sleep(SETTLE)
            before = set(sys.modules)
            assert call({"op": "fault", "robot": ROBOT, "node": "battery"})["ok"]
            wait_running(1)
            print(json.dumps(sorted(set(sys.modules) - before)), flush=True)
    finally:
        os.kill(os.getpid(), signal.SIGINT)  # the host's way to stop


def connect(control: str) -> socket.socket:
    deadline = time.monotonic() + TIMEOUT
    while True:
        connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            connection.connect(control)
            return connection
        except OSError:
            connection.close()
            if time.monotonic() >= deadline:
                raise
            time.sleep(0.05)


if __name__ == "__main__":
    threading.Thread(target=drive, args=(sys.argv[1],), daemon=True).start()
    sys.exit(host.main(["--control", sys.argv[1]]))
