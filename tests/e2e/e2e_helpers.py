"""Small helpers of the end-to-end tests: where a robot's waypoints lie in the world, speeds from
odometry, and pose watching.  Bringing fleets up is fleet.testing's job, not this module's."""

from __future__ import annotations

import itertools
import math
import threading
import time
from pathlib import Path

import yaml

from tests.checkout import FLEETS

TWO_ROBOTS = FLEETS / "two_robots.yaml"
SAFETY_STOP = FLEETS / "safety_stop.yaml"


def world_waypoints(fleet, robot: str) -> list[tuple[float, float]]:
    """The robot's controller waypoints (x,y pairs in its odom frame, whose origin is its spawn
    pose) as points of the shared world frame."""
    spec = fleet.spec.robot(robot)
    flat = fleet.expansion.robot(robot).parameters.effective()["controller"]["waypoints"]
    c, s = math.cos(spec.pose.yaw), math.sin(spec.pose.yaw)
    return [
        (spec.pose.x + c * x - s * y, spec.pose.y + s * x + c * y) for x, y in zip(flat[::2], flat[1::2], strict=False)
    ]


class RouteProgress:
    """Which waypoints of a route a robot reached, in route order, starting from the first one
    it reaches (it may be anywhere on its route when watching starts).  Call update() while
    waiting."""

    def __init__(self, fleet, robot: str, tolerance: float = 0.3):
        self.fleet, self.robot, self.tolerance = fleet, robot, tolerance
        self.points = world_waypoints(fleet, robot)
        self.reached: list[int] = []
        self.next: int | None = None

    def update(self) -> int:
        """Record the next waypoint when reached; returns how many were reached so far."""
        pose = self.fleet.pose(self.robot)
        candidates = range(len(self.points)) if self.next is None else [self.next]
        for index in candidates:
            if pose.distance_to(self.points[index]) < self.tolerance:
                self.reached.append(index)
                self.next = (index + 1) % len(self.points)
                break
        return len(self.reached)


def wait_driving(fleet, robots, sim_timeout: float = 15.0, distance: float = 0.1) -> None:
    """Wait until each robot has moved `distance`: its nodes are up *and* talking to the world.
    ("Running" only says the processes run; after a restart, DDS discovery takes a second or
    two before a node hears the world's /clock and scans.)"""
    start = {robot: fleet.pose(robot) for robot in robots}
    moved: set[str] = set()

    def all_moved() -> bool:
        moved.update(robot for robot in robots if fleet.pose(robot).distance_to(start[robot]) > distance)
        return moved == set(robots)

    fleet.wait_for(
        all_moved,
        sim_timeout=sim_timeout,
        what=f"{', '.join(robots)} to drive {distance} m",
        explain=lambda: f"moved so far: {sorted(moved)}",
    )


def wait_every_robot_left_its_spawn(fleet, distance: float = 0.2, sim_timeout: float = 30.0) -> None:
    """Wait until every simulated robot of the spec has been `distance` away from where the spec spawns it.

    From the spawn, and once is enough: under load a robot may have driven its course before the
    fleet is up (safety_stop's scout stops at its crate 1.4 m out), and a looping one passes its
    spawn point again."""
    spawns = {robot.name: (robot.pose.x, robot.pose.y) for robot in fleet.spec.robots if robot.simulated}
    moved: set[str] = set()

    def still() -> list[str]:
        moved.update(robot for robot, spawn in spawns.items() if fleet.pose(robot).distance_to(spawn) >= distance)
        return sorted(set(spawns) - moved)

    fleet.wait_for(
        lambda: not still(),
        sim_timeout=sim_timeout,
        what=f"every robot to move {distance} m",
        explain=lambda: f"not moved: {', '.join(still())}",
    )


def odom_speeds(messages, window: float = 0.5) -> list[float]:
    """Speeds (m/s) measured from odometry positions over `window` seconds of message (sim) time."""
    samples = [
        (m.header.stamp.sec + m.header.stamp.nanosec * 1e-9, m.pose.pose.position.x, m.pose.pose.position.y)
        for m in messages
    ]
    speeds = []
    start = 0
    for end in range(len(samples)):
        while samples[end][0] - samples[start][0] > window:
            start += 1
        dt = samples[end][0] - samples[start][0]
        if dt >= window * 0.8:
            speeds.append(math.hypot(samples[end][1] - samples[start][1], samples[end][2] - samples[start][2]) / dt)
    return speeds


class PoseWatch:
    """Samples every robot's pose from the world status file in a thread; reports the largest
    step between two samples (a jump: a robot teleported, the world restarted it elsewhere)."""

    def __init__(self, fleet, robots: list[str], period: float = 0.05):
        self.fleet, self.robots, self.period = fleet, robots, period
        self.samples: dict[str, list[tuple[float, float, float]]] = {robot: [] for robot in robots}  # (sim, x, y)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def __enter__(self) -> PoseWatch:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        while not self._stop.is_set():
            world = self.fleet.world() or {}
            for robot in self.robots:
                entry = world.get("robots", {}).get(robot)
                if entry is not None:
                    samples = self.samples[robot]
                    point = (world["sim_time"], entry["pose"]["x"], entry["pose"]["y"])
                    if not samples or samples[-1] != point:
                        samples.append(point)
            time.sleep(self.period)

    def path_length(self, robot: str) -> float:
        samples = self.samples[robot]
        return sum(math.hypot(x1 - x0, y1 - y0) for (_, x0, y0), (_, x1, y1) in itertools.pairwise(samples))

    def largest_jump(self, robot: str) -> float:
        """Largest distance between two consecutive samples, less what the robot could drive."""
        worst = 0.0
        samples = self.samples[robot]
        for (t0, x0, y0), (t1, x1, y1) in itertools.pairwise(samples):
            drivable = 1.0 * max(t1 - t0, 0.0)  # the light model's max_linear_speed is 1 m/s
            worst = max(worst, math.hypot(x1 - x0, y1 - y0) - drivable)
        return worst


def spec_with(source: Path, directory: Path, change) -> Path:
    """A copy of a spec file changed by change(data) (written under `directory`)."""
    data = yaml.safe_load(source.read_text())
    change(data)
    path = directory / f"{source.stem}-{time.monotonic_ns()}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def node_pids(view) -> dict[str, set[int]]:
    return {row.name: row.pids for row in view.robots}
