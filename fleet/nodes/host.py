"""host: the fleet nodes of many robots in one rclpy process (isolation: agent).

`python -m fleet.nodes.host --control SOCKET` starts rclpy with no node, listens on the Unix
socket SOCKET and waits for its agent (fleet.runtime.hosting) to add robots.  The channel
carries JSON lines, one request and one reply each (`{"ok": true, ...}` or `{"ok": false,
"error": "..."}`); a malformed request gets an error reply and changes nothing:

    {"op": "add", "robot": R, "respawn": true, "respawn_delay": 1.0,
     "nodes": [{"executable": "controller", "ros_args": ["--ros-args", "-r", "__ns:=/r1", ...],
                "logger": "r1.controller"}]}
                                -> nodes it cannot create: {"ok": false, "error", "state"}
                                   (backoff: tried again; failed: respawn is off)
    {"op": "remove", "robot": R}
    {"op": "status"}            -> {"ok": true, "robots": {R: {"state", "restarts", "uptime", "error"}}}
    {"op": "fault", "robot": R, "node": NAME}   fault injection (tests, drills): that node's next
                                                 timer callback raises

Each node is created as composite does (its own cli_args, no global arguments), so names,
namespaces, parameter files, -p values and remappings are exactly those of a process of its own.
The agent files the host's output by the logger that printed each line, so every line the host
writes about a robot's node is logged under that node's logger: the "logger" of its add request
when the node could not even be made.
A robot's fault stays its own: an exception escaping a callback of one of its nodes is caught
here, logged with that node's logger (so it lands in that robot's node log), and that robot's
nodes alone are destroyed and created again after a backoff, counting a restart for it.
Requests are read on a thread and carried out on the main thread, between callbacks: rclpy
entities are created and destroyed only where the executor runs.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import signal
import socket
import threading
import time
import traceback
from concurrent.futures import Future
from dataclasses import dataclass, field
from typing import Any

# What a robot's failure needs, imported at start-up, before any robot runs: a failure is carried
# out on the executor thread, where a first import stalls every robot of the host (importing
# fleet.runtime.supervisor there took 0.28 s, pydantic and all: the neighbours' cmd_vel stopped
# past the world's command timeout).  fleet.rules is the standard library only, so this costs
# the host's start-up nothing (rclpy, which does cost, still waits for main).
from fleet.rules import STABLE_AFTER, backoff_delay

PROGRAM = "host"
WAIT = 0.2  # s: longest the executor waits before looking at requests and due restarts again
# s: a robot that failed is made again no sooner than this after the host started.  Nodes made
# and destroyed again and again in a participant the discovery server has only just met can cost
# another robot of the host its discovery for good (Fast DDS 2.14.5; docs/architecture.md, "Known
# problem": 22 of 551 trials on a loaded machine, none of 243 with this wait).
YOUNG = 3.0
MAX_LINE = 1 << 20  # bytes of one request line


class RequestError(ValueError):
    """A request that cannot be carried out; its message is the error reply."""


@dataclass
class HostedRobot:
    name: str
    nodes: list[tuple[str, list[str], str]]  # (executable, ros arguments, its logger's name)
    respawn: bool = True
    respawn_delay: float = 1.0
    live: list[Any] = field(default_factory=list)  # its rclpy nodes while it runs
    state: str = "starting"  # running | backoff | failed
    restarts: int = 0
    started_at: float = 0.0
    restart_at: float | None = None
    failures_in_row: int = 0
    error: str = ""


def parse_request(line: bytes) -> dict[str, Any]:
    """The request on one line, checked for shape; RequestError says what is wrong."""
    try:
        request = json.loads(line)
    except (ValueError, UnicodeDecodeError) as error:
        raise RequestError(f"not JSON: {error}") from None
    if not isinstance(request, dict) or not isinstance(request.get("op"), str):
        raise RequestError('a request is a JSON object with "op"')
    op = request["op"]
    if op not in ("add", "remove", "status", "fault"):
        raise RequestError(f"unknown op {op!r} (ops: add, remove, status, fault)")
    if op != "status" and not (isinstance(request.get("robot"), str) and request["robot"]):
        raise RequestError(f'{op} needs "robot": a name')
    if op == "fault" and not isinstance(request.get("node"), str):
        raise RequestError('fault needs "node": a node name')
    if op == "add":
        from fleet.nodes import NODES

        nodes = request.get("nodes")
        if not isinstance(nodes, list) or not nodes:
            raise RequestError('add needs "nodes": a non-empty list')
        for node in nodes:
            if not isinstance(node, dict) or node.get("executable") not in NODES:
                raise RequestError(f"each node needs an executable of {', '.join(sorted(NODES))}")
            arguments = node.get("ros_args")
            if not isinstance(arguments, list) or not all(isinstance(a, str) for a in arguments):
                raise RequestError('each node needs "ros_args": a list of strings')
            if not isinstance(node.get("logger"), str) or not node["logger"]:
                raise RequestError('each node needs "logger": the name of its logger')
        delay = request.get("respawn_delay", 1.0)
        if not isinstance(delay, (int, float)) or isinstance(delay, bool) or delay < 0:
            raise RequestError('"respawn_delay" must be a number of seconds >= 0')
    return request


class Host:
    """The robots of this process and the executor spinning their nodes (main thread only)."""

    def __init__(self, context: Any = None) -> None:
        from fleet.nodes.batch_executor import BatchExecutor

        self.executor = BatchExecutor(context=context)  # context: rclpy's default one
        self.started_at = time.monotonic()
        self.robots: dict[str, HostedRobot] = {}
        self.owner: dict[int, str] = {}  # id(node) -> robot, for the nodes alive now
        self.requests: queue.Queue[tuple[dict[str, Any], Future]] = queue.Queue()

    # -- requests (main thread) --

    def submit(self, request: dict[str, Any]) -> Future:
        """From the channel's threads: hand a request to the main thread, wake it."""
        future: Future = Future()
        self.requests.put((request, future))
        self.executor.wake()
        return future

    def carry_out(self) -> None:
        while True:
            try:
                request, future = self.requests.get_nowait()
            except queue.Empty:
                return
            try:
                future.set_result(self.handle(request))
            except RequestError as error:
                future.set_result({"ok": False, "error": str(error)})
            except Exception as error:  # a request never takes the host down
                future.set_result({"ok": False, "error": f"{type(error).__name__}: {error}"})

    def handle(self, request: dict[str, Any]) -> dict[str, Any]:
        op = request["op"]
        if op == "status":
            now = time.monotonic()
            return {
                "ok": True,
                "pid": os.getpid(),
                "robots": {
                    name: {
                        "state": robot.state,
                        "restarts": robot.restarts,
                        "uptime": round(now - robot.started_at, 3) if robot.state == "running" else 0.0,
                        "error": robot.error,
                    }
                    for name, robot in self.robots.items()
                },
            }
        name = request["robot"]
        if op == "add":
            if name in self.robots:
                raise RequestError(f"robot {name!r} is here already (remove it first)")
            robot = HostedRobot(
                name=name,
                nodes=[(node["executable"], list(node["ros_args"]), node["logger"]) for node in request["nodes"]],
                respawn=bool(request.get("respawn", True)),
                respawn_delay=float(request.get("respawn_delay", 1.0)),
            )
            self.robots[name] = robot
            self.create(robot)
            if robot.state != "running":  # backoff (tried again) or failed (respawn off)
                return {"ok": False, "error": robot.error, "state": robot.state}
            return {"ok": True}
        held = self.robots.get(name)
        if held is None:
            raise RequestError(f"no robot {name!r} here")
        if op == "remove":
            self.destroy(held)
            del self.robots[name]
            return {"ok": True}
        # fault: the named node's next timer callback raises (fault injection).
        node = next((n for n in held.live if n.get_name() == request["node"]), None)
        if node is None:
            raise RequestError(f"robot {name!r} runs no node {request['node']!r} now")

        def fail() -> None:
            raise RuntimeError(f"fault injected into {node.get_fully_qualified_name()}")

        node.create_timer(0.01, fail)
        return {"ok": True}

    # -- a robot's nodes --

    def create(self, robot: HostedRobot) -> None:
        import rclpy.logging

        from fleet.nodes.composite import _create

        for executable, ros_args, logger in robot.nodes:
            try:
                node = _create(executable, ros_args)
                robot.live.append(node)
                self.owner[id(node)] = robot.name
                self.executor.add_node(node)
            except Exception as error:  # a bad configuration fails this robot, not the host
                robot.error = " ".join(str(error).split()) or type(error).__name__
                # Under the node's logger, by which the agent files the line: a line naming no
                # logger lands in the log of whichever node printed last, maybe another robot's.
                message = f"{PROGRAM}: cannot create the nodes of robot {robot.name}: {robot.error}"
                rclpy.logging.get_logger(logger).error(message)
                self.destroy(robot)
                self.after_failure(robot)
                return
        robot.state = "running"
        robot.error = ""
        robot.started_at = time.monotonic()

    def destroy(self, robot: HostedRobot) -> None:
        for node in robot.live:
            self.owner.pop(id(node), None)
            self.executor.remove_node(node)
            try:
                node.destroy_node()
            except Exception as error:  # half-built or already broken: it is gone either way
                node.get_logger().error(f"{PROGRAM}: destroying this node of robot {robot.name}: {error}")
        robot.live = []

    def fault(self, robot: HostedRobot, node: Any, error: BaseException) -> None:
        """An exception escaped a callback of one of robot's nodes: restart that robot alone."""
        text = "".join(traceback.format_exception(error)).rstrip()
        node.get_logger().error(f"uncaught exception in a callback; restarting robot {robot.name}'s nodes\n{text}")
        robot.error = " ".join(str(error).split()) or type(error).__name__
        self.destroy(robot)
        self.after_failure(robot)

    def after_failure(self, robot: HostedRobot) -> None:
        if not robot.respawn:
            robot.state = "failed"
            return
        now = time.monotonic()
        ran_for = now - robot.started_at if robot.started_at else 0.0
        robot.failures_in_row = 1 if ran_for >= STABLE_AFTER else robot.failures_in_row + 1
        robot.state = "backoff"
        due = now + backoff_delay(robot.respawn_delay, robot.failures_in_row)
        robot.restart_at = max(due, self.started_at + YOUNG)

    def restart_due(self) -> None:
        now = time.monotonic()
        for robot in list(self.robots.values()):
            if robot.state == "backoff" and robot.restart_at is not None and now >= robot.restart_at:
                robot.restarts += 1
                robot.restart_at = None
                self.create(robot)

    # -- spinning --

    def spin_once(self) -> None:
        """Wait for callbacks (or a request: submit wakes the executor), run all found ready."""
        self.executor.spin_once(WAIT, on_error=self.callback_failed)

    def callback_failed(self, node: Any, raised: BaseException) -> None:
        robot_name = self.owner.get(id(node))
        if robot_name is None:  # a node destroyed a moment ago: nobody to restart
            node.get_logger().error(f"{PROGRAM}: exception in a callback of no live robot: {raised!r}")
            return
        self.fault(self.robots[robot_name], node, raised)

    def shutdown(self) -> None:
        for robot in self.robots.values():
            self.destroy(robot)
        self.executor.shutdown(timeout_sec=1.0)


def serve(path: str, host: Host, stopping: threading.Event) -> socket.socket:
    """Listen on the Unix socket `path`; each connection gets a thread answering its lines."""
    server = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    server.bind(path)
    os.chmod(path, 0o600)  # only the agent's user talks to its hosts
    server.listen(8)

    def answer(connection: socket.socket) -> None:
        with connection, connection.makefile("rwb") as stream:
            for line in iter(lambda: stream.readline(MAX_LINE + 1), b""):
                if stopping.is_set():
                    return
                try:
                    if len(line) > MAX_LINE:
                        raise RequestError(f"request longer than {MAX_LINE} bytes")
                    reply = host.submit(parse_request(line)).result()
                except RequestError as error:
                    reply = {"ok": False, "error": str(error)}
                stream.write(json.dumps(reply).encode() + b"\n")
                stream.flush()

    def accept() -> None:
        while not stopping.is_set():
            try:
                connection, _ = server.accept()
            except OSError:  # closed: we are stopping
                return
            threading.Thread(target=answer, args=(connection,), daemon=True, name="host-channel").start()

    threading.Thread(target=accept, daemon=True, name="host-accept").start()
    return server


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog=PROGRAM, description="Host the fleet nodes of many robots.")
    parser.add_argument("--control", required=True, help="Unix socket path of the control channel")
    args = parser.parse_args(argv)

    import rclpy
    from rclpy.signals import SignalHandlerOptions

    stop_requested: list[int] = []
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda received, _: stop_requested.append(received))
    rclpy.init(args=[PROGRAM], signal_handler_options=SignalHandlerOptions.NO)
    host = Host()
    stopping = threading.Event()
    server = serve(args.control, host, stopping)
    print(f"{PROGRAM}: ready on {args.control}", flush=True)
    try:
        while not stop_requested and rclpy.ok():
            host.carry_out()
            host.restart_due()
            host.spin_once()
    finally:
        stopping.set()
        server.close()
        host.shutdown()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
