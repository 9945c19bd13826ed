"""The world process: main loop (physics, sensors, pacing), live reload of world.yaml, status.

Everything runs in the main thread; ROS runs in a second process (ros_process), told the robots'
layout by physics row.  Per physics tick the loop only applies commands and steps; sensors,
contacts and bookkeeping run on their own (sim-time) schedules, wall-clock chores (status file,
reload check) on wall-clock schedules.
"""

from __future__ import annotations

import logging
import math
import os
import signal
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fleet.world import lidar
from fleet.world.description import (
    ObstacleSpec,
    Pose2D,
    RobotSpec,
    WorldError,
    WorldSpec,
    load_world,
    slot_steps,
)
from fleet.world.geometry import obstacle_shape, robot_shape
from fleet.world.inputs import RobotInputs
from fleet.world.physics import PhysicsWorld, SpawnError
from fleet.world.status import (
    CONTACTS_KEPT,
    Trail,
    finish_status,
    last_poses,
    last_sim_time,
    model_dict,
    obstacle_dict,
    pose_dict,
    read_status,
    write_status,
)
from fleet.world.status_writer import StatusWriter

log = logging.getLogger("fleet.world")

MARKER_PERIOD = 0.5  # s (wall): markers are for people watching RViz, whatever the sim's speed
CONTACT_SHOWN = 1.0  # s (sim): a robot's marker stays red this long after a contact
STATUS_PERIOD = 0.25  # s (wall) between status file writes
RELOAD_PERIOD = 0.5  # s (wall) between world.yaml mtime checks
MAX_LAG = 0.5  # s: in real-time mode, a world further behind than this stops trying to catch up


@dataclass
class _Robot:
    spec: RobotSpec
    angles: np.ndarray
    next_odom: float
    next_scan: float
    trail: Trail = field(default_factory=Trail)
    hits: tuple | None = None  # (x, y, yaw, angle_min, angle_increment, ranges) of the latest scan
    velocity: tuple[float, float] = (0.0, 0.0)
    model: dict[str, Any] = field(default_factory=dict)  # as the status shows it


def resume_time(previous: dict[str, Any] | None) -> float:
    """Where a restarted world's clock starts: at the time of a clean stop; after a crash, past
    what it may have published since its last status write (a jump forward is harmless to nodes
    on sim time, a jump back stalls their timers and TF)."""
    resumed = last_sim_time(previous)
    if previous is None or previous.get("stopped") is True or resumed == 0.0:
        return resumed
    rtf = previous.get("real_time_factor")
    rtf = rtf if isinstance(rtf, int | float) and 0 < rtf < 1e4 else 1.0
    return resumed + 2 * STATUS_PERIOD * max(1.0, rtf)


class WorldApp:
    def __init__(
        self,
        config: str | Path,
        status_file: str | Path | None = None,
        *,
        as_fast_as_possible: bool = False,
        bridge: Any = None,
    ) -> None:
        """bridge: a ros_process.RosProcess (None: no ROS)."""
        self.config = Path(config)
        self.status_file = Path(status_file) if status_file else None
        self.as_fast_as_possible = as_fast_as_possible
        self.spec: WorldSpec = load_world(self.config)  # WorldError: the caller exits 2
        self._config_stamp = self._stamp()
        self.bridge = bridge
        self.physics = PhysicsWorld(self.spec.physics_rate)
        self.robots: dict[str, _Robot] = {}
        self.errors: dict[str, dict[str, Any]] = {}  # key -> {"sim_time", "message"}: current problems
        self.contacts_count = 0
        self.contacts_last: deque[dict] = deque(maxlen=CONTACTS_KEPT)
        self.stopping = False
        self._obstacle_shapes: list = []
        self._tick = 0
        # Lidar batches, contact checks, trail samples and command pick-ups run every this many ticks.
        self._slot_every = slot_steps(self.spec.physics_rate)
        self._next_clock = 0.0
        self._next_odom = 0.0  # sim time: the earliest next_odom of all robots
        self._next_trail = 0.0  # sim time: the earliest next trail sample of all robots
        self._layout: tuple | None = None  # (physics.row the bridge was last given, cmd_timeouts by row)
        self._generation = 0  # of the layout
        self._inputs = RobotInputs.empty(0, 0)  # the robots' latest commands, batteries, subscribers
        self._footprints: tuple | None = None  # physics.row it was made for, round rows, radii, other robots
        self._obstacle_scene: lidar.Scene | None = None  # what lidars see of the obstacles
        self._writer: StatusWriter | None = None  # started by the first run(), kept until close()
        self._next_markers = 0.0  # time.monotonic() of the next marker publication
        self._rtf_window: deque[tuple[float, float]] = deque()
        self.real_time_factor = 0.0
        for obstacle in self.spec.obstacles:
            self._add_obstacle(obstacle)
        # A restarted world resumes where it stopped: its time (nodes on sim time would otherwise
        # see /clock jump back, and their timers stall) and its robots' poses.
        previous = read_status(self.status_file) if self.status_file else None
        if previous is not None and previous.get("fleet") != self.spec.fleet:
            previous = None  # another fleet's file: start afresh
        self.physics.sim_time = resume_time(previous)
        restored = last_poses(previous, {robot.name: robot.pose for robot in self.spec.robots})
        for robot in self.spec.robots:
            self._spawn(robot, restored.get(robot.name))

    # -- robots and obstacles ----------------------------------------------------------------------

    def _add_obstacle(self, spec: ObstacleSpec) -> None:
        self.physics.add_obstacle(spec)
        self._layout = None  # the bridge draws obstacles
        self._obstacle_shapes = [obstacle_shape(s) for _, s in self.physics.obstacles.values()]
        self._obstacle_scene = None

    def _remove_obstacle(self, name: str) -> None:
        self.physics.remove_obstacle(name)
        self._layout = None
        self._obstacle_shapes = [obstacle_shape(s) for _, s in self.physics.obstacles.values()]
        self._obstacle_scene = None

    def _error(self, key: str, message: str) -> None:
        if self.errors.get(key, {}).get("message") != message:
            log.error(message)
            self.errors[key] = {"sim_time": round(self.physics.sim_time, 3), "message": message}

    def _spawn(self, spec: RobotSpec, restored: Pose2D | None = None) -> bool:
        """Place a robot (at its restored pose when that spot is free, else at its configured one);
        a refused spawn is reported under errors and retried at the next reload check."""
        pose = spec.pose
        if restored is not None and self.physics.placement_problem(spec.name, spec.model, restored) is None:
            pose = restored
        try:
            self.physics.add_robot(spec.name, spec.model, pose)
        except SpawnError as error:
            self._error(f"robot:{spec.name}", f"robot '{spec.name}' not spawned: {error}")
            return False
        self.errors.pop(f"robot:{spec.name}", None)
        now = self.physics.sim_time
        lidar_spec = spec.lidar
        period = 1.0 / lidar_spec.rate
        # Spread the scans of many robots over the scan period instead of all on one tick.
        phase = (len(self.robots) * 0.137 % 1.0) * period
        self.robots[spec.name] = _Robot(
            spec=spec,
            angles=lidar.beam_angles(lidar_spec.angle_min, lidar_spec.increment, lidar_spec.beams),
            next_odom=now,
            next_scan=now + phase,
            model=model_dict(spec.model),
        )
        self._next_odom = min(self._next_odom, now)
        self._next_trail = min(self._next_trail, now)
        log.info(
            "robot '%s' (%s) spawned at (%.2f, %.2f, yaw %.2f)", spec.name, spec.model.type, pose.x, pose.y, pose.yaw
        )
        return True

    def _despawn(self, name: str) -> None:
        self.robots.pop(name, None)
        if name in self.physics.robots:
            self.physics.remove_robot(name)
        log.info("robot '%s' removed", name)

    # -- reload ------------------------------------------------------------------------------------

    def _stamp(self) -> tuple[int, int] | None:
        try:
            st = os.stat(self.config)
        except OSError:
            return None
        return st.st_mtime_ns, st.st_size

    def check_reload(self) -> None:
        stamp = self._stamp()
        if stamp != self._config_stamp:
            self._config_stamp = stamp
            try:
                new = load_world(self.config)
            except WorldError as error:
                self._error("config", f"world description not applied (the world keeps running as before): {error}")
                return
            self.errors.pop("config", None)
            self.apply(new)
        else:
            # Retry refused spawns: the spot may have been cleared since.
            for spec in self.spec.robots:
                if spec.name not in self.robots:
                    self._spawn(spec)

    def apply(self, new: WorldSpec) -> None:
        """Make the running world match `new` without touching what did not change."""
        old = self.spec
        if new.physics_rate != old.physics_rate:
            log.warning(
                "physics_rate change (%g -> %g Hz) applies at the next restart", old.physics_rate, new.physics_rate
            )
        old_obstacles = {o.name: o for o in old.obstacles}
        new_obstacles = {o.name: o for o in new.obstacles}
        for name, spec in old_obstacles.items():
            if new_obstacles.get(name) != spec and name in self.physics.obstacles:
                self._remove_obstacle(name)
        for name, spec in new_obstacles.items():
            if name not in self.physics.obstacles:
                self._add_obstacle(spec)
        wanted = {r.name: r for r in new.robots}
        for name in list(self.robots):
            if name not in wanted:
                self._despawn(name)
        for key in [k for k in self.errors if k.startswith("robot:") and k[6:] not in wanted]:
            self.errors.pop(key)
        self.spec = WorldSpec(**{**new.__dict__, "physics_rate": old.physics_rate})
        for name, robot_spec in wanted.items():
            current = self.robots.get(name)
            if current is None:
                self._spawn(robot_spec)
                continue
            change = current.spec.reload_change(robot_spec)
            if change == "respawn":
                log.info("robot '%s' has a new spawn pose: respawning it there", name)
                self._despawn(name)
                self._spawn(robot_spec)
            elif change == "rebuild":
                x, y, yaw = self.physics.robots[name].pose()
                self._despawn(name)
                self._spawn(robot_spec, Pose2D(x, y, yaw))

    # -- the loop ----------------------------------------------------------------------------------

    def step(self) -> None:
        """One physics tick plus whatever sensors are due."""
        physics = self.physics
        now = physics.sim_time
        bridge = self.bridge
        if bridge is not None:
            timeouts = self._sync_layout()  # robots come and go between steps (reload)
            if self._tick % self._slot_every == 0:
                # Commands change at controller rates (~20 Hz): picking them up once a slot adds
                # at most one slot of latency and saves work per robot per tick.
                self._inputs = bridge.inputs()
                physics.command_all(self._inputs.live_commands(timeouts, now))
        physics.step()
        self._tick += 1
        now = physics.sim_time
        if now >= self._next_odom:
            self._odometry(now)
        if self._tick % self._slot_every == 0:
            self._slot(now)
        if bridge is not None and now >= self._next_clock:
            self._next_clock = max(self._next_clock + 1.0 / self.spec.clock_rate, now)
            bridge.publish_clock(now)
        if bridge is not None:
            bridge.flush()

    def _sync_layout(self) -> np.ndarray:
        """Give the bridge the robots by physics row and the obstacles when they changed;
        the robots' cmd_timeouts by row."""
        row, obstacles = self.physics.row, self.physics.obstacles
        if self._layout is None or self._layout[0] is not row:
            specs = [self.robots[name].spec for name in row]
            timeouts = np.array([spec.cmd_timeout for spec in specs], dtype=float)
            self._layout = (row, timeouts)
            if self.bridge is not None:
                self._generation += 1
                self.bridge.set_robots(self._generation, specs, [spec for _, spec in obstacles.values()])
                self._inputs = self.bridge.inputs()
        return self._layout[1]

    def _odometry(self, now: float) -> None:
        """Odometry of the robots due now, read and published as one batch."""
        due = [robot for robot in self.robots.values() if now >= robot.next_odom]
        for robot in due:
            robot.next_odom = max(robot.next_odom + 1.0 / robot.spec.odom_rate, now)
        self._next_odom = min((robot.next_odom for robot in self.robots.values()), default=math.inf)
        if not due:
            return
        rows = np.array([self.physics.row[robot.spec.name] for robot in due], dtype=np.int64)
        poses = self.physics.poses()[rows]
        velocities = self.physics.velocities(rows, poses[:, 2])
        for robot, (linear, _, angular) in zip(due, velocities.tolist(), strict=True):
            robot.velocity = (linear, angular)
        if self.bridge is not None:
            self.bridge.publish_odom(rows, now, poses, velocities)

    def _slot(self, now: float) -> None:
        """Lidars due now (one scene for all of them), contacts, trails."""
        due = [robot for robot in self.robots.values() if now >= robot.next_scan]
        poses = self.physics.poses()
        row = self.physics.row
        if due:
            scene = self._scene(poses)
            # One batched cast per beam layout (usually one for the whole fleet).
            groups: dict[tuple, list[_Robot]] = {}
            for robot in due:
                lid = robot.spec.lidar
                groups.setdefault((lid.beams, lid.angle_min, lid.angle_max, lid.range_min, lid.range_max), []).append(
                    robot
                )
            for group in groups.values():
                lid = group[0].spec.lidar
                rows = np.array([row[r.spec.name] for r in group], dtype=np.int64)
                group_poses = poses[rows]
                all_ranges = lidar.cast_many(scene, group_poses, rows, group[0].angles, lid.range_min, lid.range_max)
                for robot, pose, ranges in zip(group, group_poses.tolist(), all_ranges, strict=False):
                    robot.next_scan = max(robot.next_scan + 1.0 / robot.spec.lidar.rate, now)
                    robot.hits = (*pose, lid.angle_min, lid.increment, ranges)  # points only for the status
                if self.bridge is not None:
                    self.bridge.publish_scans(rows, now, all_ranges)
        for event in self.physics.poll_contacts():
            self.contacts_count += 1
            self.contacts_last.append(event.as_dict())
            log.info("contact %s: %s - %s at t=%.2f", event.kind, event.a, event.b, event.sim_time)
        if now >= self._next_trail:
            for name, robot in self.robots.items():
                x, y, _ = poses[row[name]].tolist()
                robot.trail.sample(now, x, y)
            self._next_trail = min((robot.trail.next_time for robot in self.robots.values()), default=math.inf)
        if self.bridge is not None and time.monotonic() >= self._next_markers:
            self._next_markers = time.monotonic() + MARKER_PERIOD
            self.bridge.publish_markers(now, poses, self._touching(now))

    def _scene(self, poses: np.ndarray) -> lidar.Scene:
        """What the lidars see: obstacles and robots at `poses`; a robot's shapes are owned by its
        row in poses.  The obstacles' part is made once; round robots (most of a large fleet) are
        added as arrays."""
        row = self.physics.row
        if self._footprints is None or self._footprints[0] is not row:
            models = {name: self.physics.robots[name].model for name in row}
            round_rows = np.array([i for name, i in row.items() if models[name].is_round], dtype=np.int64)
            radii = np.array([models[name].radius for name in row], dtype=float)[round_rows]
            others = [(models[name], i) for name, i in row.items() if not models[name].is_round]
            self._footprints = (row, round_rows, radii, others)
        _, round_rows, radii, others = self._footprints
        if self._obstacle_scene is None:
            shapes = self._obstacle_shapes
            self._obstacle_scene = lidar.Scene.build(shapes, [-1] * len(shapes))
        scene = self._obstacle_scene.joined(lidar.Scene.circles(poses[round_rows, :2], radii, round_rows))
        if others:
            shapes = [robot_shape(model, *poses[i].tolist()) for model, i in others]
            scene = scene.joined(lidar.Scene.build(shapes, [i for _, i in others]))
        return scene

    def _touching(self, now: float) -> set[str]:
        """Robots and obstacles in a contact within the last CONTACT_SHOWN seconds (drawn red)."""
        return {
            name
            for event in self.contacts_last
            if now - event["sim_time"] <= CONTACT_SHOWN
            for name in (event["a"], event["b"])
        }

    def status_parts(self) -> dict[str, Any]:
        """The status document with each robot's trail and latest scan still raw
        (fleet.world.status.finish_status makes the document of them)."""
        robots = {}
        self._sync_layout()  # the status may follow a reload that no step has seen yet
        poses, row, inputs = self.physics.poses().tolist(), self.physics.row, self._inputs
        ros = self.bridge is not None
        for name, robot in self.robots.items():
            i = row[name]
            x, y, yaw = poses[i]
            robots[name] = {
                "pose": {"x": round(x, 4), "y": round(y, 4), "yaw": round(yaw, 4)},
                "spawn": pose_dict(robot.spec.pose),  # unrounded: compared with world.yaml's at a restart
                "velocity": {"linear": round(robot.velocity[0], 4), "angular": round(robot.velocity[1], 4)},
                "battery": inputs.battery_of(i) if ros else None,
                "model": robot.model,
                "namespace": robot.spec.namespace,
                **(inputs.link(i) if ros else {}),
                "trail": list(robot.trail.points),
                "hits": robot.hits,
            }
        return {
            "fleet": self.spec.fleet,
            "sim_time": round(self.physics.sim_time, 4),
            "wall_time": round(time.time(), 3),
            "real_time_factor": round(self.real_time_factor, 3),
            "physics_rate": self.spec.physics_rate,
            "robots": robots,
            "obstacles": [obstacle_dict(spec) for _, spec in self.physics.obstacles.values()],
            "contacts": {"count": self.contacts_count, "last": list(self.contacts_last)},
            "errors": list(self.errors.values()),
        }

    def status(self) -> dict[str, Any]:
        return finish_status(self.status_parts())

    def write_status(self, stopped: bool = False, writer: StatusWriter | None = None) -> None:
        """Write the status file now, or hand it to `writer` (skipped while it is busy)."""
        if self.status_file is None:
            return
        if writer is not None:
            writer.submit({**self.status_parts(), "stopped": stopped})
        else:
            write_status(self.status_file, {**self.status(), "stopped": stopped})

    def _measure_rtf(self, wall: float) -> None:
        window = self._rtf_window
        window.append((wall, self.physics.sim_time))
        while len(window) > 2 and wall - window[0][0] > 2.0:
            window.popleft()
        (w0, s0), (w1, s1) = window[0], window[-1]
        if w1 > w0:
            self.real_time_factor = (s1 - s0) / (w1 - w0)

    def run(self, sim_duration: float | None = None) -> None:
        """Step until stopped (signal, or sim_duration of sim time has passed)."""
        self._measure_rtf(time.monotonic())
        if self.status_file is not None and self._writer is None and not self.stopping:
            self._writer = StatusWriter(self.status_file)
        try:
            self._loop(sim_duration, self._writer)
        finally:
            if self._writer is not None:
                self._writer.settle()  # its last status must not land after the one below
        self._measure_rtf(time.monotonic())
        self.write_status(stopped=True)

    def _loop(self, sim_duration: float | None, writer: StatusWriter | None) -> None:
        start_sim = self.physics.sim_time
        dt = self.physics.dt
        wall_ref, sim_ref = time.monotonic(), self.physics.sim_time
        next_status = next_reload = wall_ref
        while not self.stopping:
            if sim_duration is not None and self.physics.sim_time - start_sim >= sim_duration - dt / 2:
                break
            if self.bridge is not None and not self.bridge.ok():
                break
            self.step()
            wall = time.monotonic()
            if self.spec.real_time and not self.as_fast_as_possible:
                ahead = (self.physics.sim_time - sim_ref) - (wall - wall_ref)
                if ahead > 0.001:
                    time.sleep(ahead)
                    wall = time.monotonic()
                elif ahead < -MAX_LAG:  # too slow for real time: run flat out, do not burst later
                    wall_ref, sim_ref = wall, self.physics.sim_time
            if wall >= next_status:
                next_status = wall + STATUS_PERIOD
                self._measure_rtf(wall)
                self.write_status(writer=writer)
            if wall >= next_reload:
                next_reload = wall + RELOAD_PERIOD
                self.check_reload()

    def close(self) -> None:
        if self._writer is not None:
            self._writer.close()
            self._writer = None
        if self.bridge is not None:
            self.bridge.close()
            self.bridge = None
        self.physics.close()


def run_world(
    config: str | Path,
    status_file: str | Path | None = None,
    *,
    as_fast_as_possible: bool = False,
    ros_args: list[str] | None = None,
    sim_duration: float | None = None,
) -> None:
    """`fleet world` and `fleet_nodes/world`: validate, start ROS, run until SIGINT/SIGTERM.

    An invalid world.yaml raises WorldError before anything starts (the caller prints one line
    and exits 2)."""
    if not logging.getLogger().handlers:
        logging.basicConfig(level=logging.INFO, format="[world] %(levelname)s: %(message)s")
    from fleet.world.ros_process import RosProcess

    bridge = RosProcess(ros_args)
    app = None
    try:
        app = WorldApp(config, status_file, as_fast_as_possible=as_fast_as_possible, bridge=bridge)

        def _stop(signum, frame):
            app.stopping = True

        signal.signal(signal.SIGINT, _stop)
        signal.signal(signal.SIGTERM, _stop)
        log.info(
            "world '%s' running: %d robots, %d obstacles, %s",
            app.spec.fleet,
            len(app.robots),
            len(app.physics.obstacles),
            "as fast as possible" if as_fast_as_possible or not app.spec.real_time else "real time",
        )
        app.run(sim_duration)
        if not bridge.ok():
            raise bridge.gone()
    finally:
        if app is not None:
            app.close()
        else:
            bridge.close()
