"""The world's ROS side in a process of its own, beside the physics process.

Why: stepSimulation, pose reads and lidar casting keep the physics thread busy, and publishing
tens of thousands of messages a second (500 robots' odometry at 50 Hz and scans at 10 Hz) took
another fifth of its time under the same GIL.  In a second process the two run on two cores.

The physics process (`RosProcess`) batches what one step publishes and sends it as one message
over a socket pair; the ROS process (`serve`, a RosBridge) publishes it.  Inputs come back
asynchronously: the physics side asks for a snapshot and takes the reply on a later slot (one
request in flight, so replies never pile up), remapping it by name when the layout changed in
between.  A layout change itself (`set_robots`) waits for the ROS side, so every publication
after it names the new rows.

The ROS process ignores SIGINT and SIGTERM (the world stops it after its last status) and exits
when the physics process closes the socket; the kernel kills it when the physics process dies.
"""

from __future__ import annotations

import json
import logging
import queue
import signal
import socket
import subprocess
import sys
import threading
from multiprocessing.connection import Connection
from typing import Any

import numpy as np

from fleet.errors import EXIT_FAILURE, FleetError
from fleet.lifetime import helper_of_parent
from fleet.world.description import ObstacleSpec, RobotSpec
from fleet.world.inputs import RobotInputs

log = logging.getLogger("fleet.world")

START_TIMEOUT = 120.0  # s for the ROS process to import rclpy and create its node (a loaded machine)
LAYOUT_TIMEOUT = 300.0  # s for it to create the publishers of a new layout (hundreds of robots)
STOP_TIMEOUT = 5.0  # s for it to exit once asked

# What the physics side may ask of the bridge: RosBridge methods that take plain data
_FORWARDED = ("publish_odom", "publish_scans", "publish_clock", "publish_markers", "hold")


class RosSideGone(FleetError):
    """The ROS process exited or stopped answering: the world cannot go on without it (it exits
    with this one line and status 1, and its supervisor restarts it)."""

    exit_code = EXIT_FAILURE


class RosProcess:
    """The physics side's handle on the ROS process: the RosBridge interface, over a socket."""

    def __init__(self, ros_args: list[str] | None = None) -> None:
        ours, theirs = socket.socketpair()
        self._process = subprocess.Popen(
            [sys.executable, "-m", "fleet.world.ros_process", str(theirs.fileno()), json.dumps(ros_args or [])],
            pass_fds=[theirs.fileno()],
            # Dead with the world even when the world is SIGKILLed (its supervisor's own exit does
            # that): reading the closed socket and closing rclpy would outlive it by seconds.
            preexec_fn=helper_of_parent,
        )
        theirs.close()
        self._conn = Connection(ours.detach())
        self._batch: list[tuple] = []
        self._names: list[str] = []
        self._generation = 0
        self._inputs = RobotInputs.empty(0, 0)
        self._asked = False
        try:
            self._expect("ready", START_TIMEOUT)
        except RosSideGone:
            self.close()
            raise

    def ok(self) -> bool:
        return self._process.poll() is None

    def _send(self, message: Any) -> None:
        try:
            self._conn.send(message)
        except OSError as error:  # BrokenPipeError, ConnectionResetError: it is gone
            raise self.gone() from error

    def gone(self) -> RosSideGone:
        """The error saying the ROS process exited, with its exit code."""
        try:
            code = self._process.wait(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            code = None
        return RosSideGone(f"the world's ROS process exited (code {code})")

    def _receive(self, timeout: float | None) -> tuple:
        try:
            if timeout is not None and not self._conn.poll(timeout):
                raise RosSideGone(f"the world's ROS process did not answer within {timeout:g} s")
            reply = self._conn.recv()
        except (EOFError, OSError) as error:
            raise self.gone() from error
        if reply[0] == "inputs":
            self._asked = False
            if reply[1].generation == self._generation:
                self._inputs = reply[1]
        return reply

    def _expect(self, kind: str, timeout: float) -> tuple:
        while True:
            reply = self._receive(timeout)
            if reply[0] == kind:
                return reply

    def flush(self) -> None:
        """Send what this step published, as one message."""
        if self._batch:
            batch, self._batch = self._batch, []
            self._send(batch)

    def set_robots(self, generation: int, robots: list[RobotSpec], obstacles: list[ObstacleSpec]) -> None:
        names = [spec.name for spec in robots]
        self._inputs = self._inputs.remapped(self._names, names, generation)
        self._names, self._generation = names, generation
        self._batch.append(("set_robots", generation, robots, obstacles))
        self.flush()
        self._expect("set_robots", LAYOUT_TIMEOUT)

    def inputs(self) -> RobotInputs:
        """The latest snapshot received (at most a slot or two old); asks for the next one."""
        while self._conn.poll():
            self._receive(None)
        if not self._asked:
            self._batch.append(("inputs",))
            self._asked = True
            self.flush()
        return self._inputs

    def publish_odom(self, rows: np.ndarray, sim_time: float, poses: np.ndarray, velocities: np.ndarray) -> None:
        self._batch.append(("publish_odom", rows, sim_time, poses, velocities))

    def publish_scans(self, rows: np.ndarray, sim_time: float, ranges: np.ndarray) -> None:
        self._batch.append(("publish_scans", rows, sim_time, ranges.astype(np.float32)))  # as published: half the bytes

    def publish_clock(self, sim_time: float) -> None:
        self._batch.append(("publish_clock", sim_time))

    def publish_markers(self, sim_time: float, poses: np.ndarray, touching: set[str]) -> None:
        self._batch.append(("publish_markers", sim_time, poses, touching))

    def hold(self, commands: np.ndarray) -> None:
        self._batch.append(("hold", commands))
        self.flush()

    def close(self) -> None:
        if self.ok():
            try:
                self._batch.append(("close",))
                self.flush()
                self._process.wait(timeout=STOP_TIMEOUT)
            except (RosSideGone, subprocess.TimeoutExpired):
                self._process.kill()
                self._process.wait()
        self._conn.close()


def serve(conn: Connection, ros_args: list[str]) -> None:
    """The ROS process: a RosBridge doing what the physics side sends, until told to stop."""
    from fleet.world.ros_bridge import RosBridge

    bridge = RosBridge(ros_args)
    # Replies go out from a thread of their own: if the physics side is slow to read them, this
    # process still reads its publications, so neither side can block the other for good.
    replies: queue.Queue[tuple | None] = queue.Queue()

    def send_replies() -> None:
        while (reply := replies.get()) is not None:
            try:
                conn.send(reply)
            except OSError:
                return

    sender = threading.Thread(target=send_replies, name="ros-replies", daemon=True)
    sender.start()
    replies.put(("ready",))
    try:
        while True:
            try:
                batch = conn.recv()
            except (EOFError, OSError):
                return  # the physics process is gone
            for kind, *args in batch:
                if kind == "close":
                    return
                if kind == "inputs":
                    replies.put(("inputs", bridge.inputs()))
                elif kind == "set_robots":
                    bridge.set_robots(*args)
                    replies.put(("set_robots", args[0]))
                elif kind in _FORWARDED:
                    getattr(bridge, kind)(*args)
                else:
                    raise ValueError(f"unknown request from the physics process: {kind!r}")
    finally:
        replies.put(None)
        sender.join(timeout=STOP_TIMEOUT)
        bridge.close()


def main(argv: list[str]) -> int:
    signal.signal(signal.SIGTERM, signal.SIG_IGN)  # the physics process says when to stop (SIGINT: helper_of_parent)
    logging.basicConfig(level=logging.INFO, format="[world] %(levelname)s: %(message)s")
    conn = Connection(int(argv[0]))
    try:
        serve(conn, json.loads(argv[1]))
    finally:
        conn.close()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
