"""The pybullet world: obstacles, robots (light or husky), stepping, poses and contacts.

No ROS here, so physics can be tested and benchmarked alone.  One DIRECT client per PhysicsWorld.
"""

from __future__ import annotations

import contextlib
import math
import os
from dataclasses import dataclass

import numpy as np
import pybullet as pb
import pybullet_data

from fleet.world.description import ModelSpec, ObstacleSpec, Pose2D, slot_steps
from fleet.world.geometry import Shape, obstacle_shape, placement_problem, robot_shape

GRAVITY = -9.81
LIGHT_HEIGHT = 0.3  # collision height of the light body; obstacles lower than its bottom are not hit
LIGHT_Z = LIGHT_HEIGHT / 2 + 0.02  # floats 2 cm above the ground: it never touches the plane
HUSKY_Z = 0.16  # base_link height with the wheels (radius 0.178, axle 0.033 above base) on the ground


@contextlib.contextmanager
def _quiet_c_output():
    """pybullet's URDF importer prints a warning per inertia-less link straight to fd 1/2, which
    would bury our log lines; silence those file descriptors while it runs."""
    saved = [os.dup(1), os.dup(2)]
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in [*saved, devnull]:
            os.close(fd)


# Fixed links merged into their parent: the husky's ten links (base, IMU, plates, bumpers, rails
# on fixed joints) become a base with four wheels, which makes its step ~30% cheaper with the same
# masses and contacts.  Cylinders collide as cylinders instead of as convex hulls of them.
URDF_FLAGS = pb.URDF_MERGE_FIXED_LINKS | pb.URDF_USE_IMPLICIT_CYLINDER


def _load_urdf(client: int, path: str, pose: Pose2D, z: float) -> int:
    with _quiet_c_output():
        return pb.loadURDF(
            path,
            basePosition=(pose.x, pose.y, z),
            baseOrientation=flat_quaternion(pose.yaw),
            flags=URDF_FLAGS,
            physicsClientId=client,
        )


class SpawnError(Exception):
    """A robot cannot be placed where it was asked to be."""


def yaw_of(quaternion) -> float:
    x, y, z, w = quaternion
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _yaws(quaternions: np.ndarray) -> np.ndarray:
    """yaw_of for rows of quaternions."""
    x, y, z, w = quaternions.T
    return np.arctan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def flat_quaternion(yaw: float) -> tuple[float, float, float, float]:
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def _frame_positions(positions: np.ndarray, quaternions: np.ndarray, com_offsets: np.ndarray) -> np.ndarray:
    """Positions of base frames from those of their centres of mass (rows)."""
    return positions - _rotated(quaternions, com_offsets)


def _rotated(quaternions: np.ndarray, vectors: np.ndarray) -> np.ndarray:
    """Rows of vectors rotated by rows of quaternions (x, y, z, w)."""
    u, w = quaternions[:, :3], quaternions[:, 3:]
    t = 2.0 * np.cross(u, vectors)
    return vectors + w * t + np.cross(u, t)


@dataclass
class RobotState:
    x: float
    y: float
    yaw: float
    linear: float  # m/s along the body x axis
    lateral: float  # m/s along the body y axis (non-zero only when pushed)
    angular: float  # rad/s about z


class _Robot:
    """Common part: a body id and its model (the commands are PhysicsWorld's, by row)."""

    def __init__(self, client: int, name: str, model: ModelSpec, body: int) -> None:
        self.client = client
        self.name = name
        self.model = model
        self.body = body
        # pybullet reports a base's centre of mass; the robot's pose is its base frame, this far
        # from it (body frame; zero but for bodies whose merged links moved the centre of mass).
        self.com_offset = tuple(pb.getDynamicsInfo(body, -1, physicsClientId=client)[3])

    def before_step(self, linear: float, angular: float) -> None:
        """Apply the command (already within the model's limits) to the joints."""
        raise NotImplementedError

    def state(self) -> RobotState:
        x, y, yaw = self.pose()
        (vx, vy, _), (_, _, wz) = pb.getBaseVelocity(self.body, physicsClientId=self.client)
        c, s = math.cos(yaw), math.sin(yaw)
        return RobotState(x, y, yaw, c * vx + s * vy, -s * vx + c * vy, wz)

    def pose(self) -> tuple[float, float, float]:
        pos, orn = pb.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
        x, y, _ = _frame_positions(np.array([pos]), np.array([orn]), np.array([self.com_offset]))[0].tolist()
        return x, y, yaw_of(orn)


class LightRobot(_Robot):
    """One rigid cylinder driven by setting its base velocity.

    It never touches the ground (collisions with the plane are filtered out).  Without URDF robots
    the world has no gravity, the body keeps its velocity between updates (no damping) and the
    velocity is refreshed at ~60 Hz (heading and command); with URDF robots gravity is on and the
    velocity is set every tick with an upward g*dt that cancels what gravity adds during the step.
    Contacts with robots and obstacles still go through the solver, which is what keeps bodies
    from passing through each other.  Any tilt or height drift a contact causes is undone by
    resetting the pose flat (rare, so cheap).
    """

    def __init__(self, client: int, name: str, model: ModelSpec, pose: Pose2D, plane: int) -> None:
        shape = pb.createCollisionShape(
            pb.GEOM_CYLINDER, radius=model.radius, height=LIGHT_HEIGHT, physicsClientId=client
        )
        body = pb.createMultiBody(
            baseMass=10.0,
            baseCollisionShapeIndex=shape,
            basePosition=(pose.x, pose.y, LIGHT_Z),
            baseOrientation=flat_quaternion(pose.yaw),
            physicsClientId=client,
        )
        # Frictionless so a robot slides along walls instead of snagging; large roll/pitch inertia so
        # contacts barely tilt it; no damping (velocity is set every tick anyway); never sleeps.
        pb.changeDynamics(
            body,
            -1,
            lateralFriction=0.0,
            spinningFriction=0.0,
            rollingFriction=0.0,
            restitution=0.0,
            linearDamping=0.0,
            angularDamping=0.0,
            localInertiaDiagonal=(1e3, 1e3, 0.5 * 10.0 * model.radius**2),
            activationState=pb.ACTIVATION_STATE_DISABLE_SLEEPING,
            physicsClientId=client,
        )
        pb.setCollisionFilterPair(body, plane, -1, -1, 0, physicsClientId=client)
        super().__init__(client, name, model, body)


class HuskyRobot(_Robot):
    """pybullet_data's husky URDF, skid-steered through velocity motors on its four wheels."""

    MAX_WHEEL_FORCE = 60.0  # N*m per wheel
    WHEEL_RADIUS = 0.17775  # from husky.urdf
    # Skid steering slips: with the URDF's wheel friction the body turns at ~0.38 of the rate the
    # plain diff-drive formula predicts (measured with the fixed links merged), so the wheel speed
    # difference is scaled up.
    SKID_FACTOR = 2.6

    def __init__(self, client: int, name: str, model: ModelSpec, pose: Pose2D) -> None:
        body = _load_urdf(client, "husky/husky.urdf", pose, HUSKY_Z)
        super().__init__(client, name, model, body)
        self.left: list[int] = []
        self.right: list[int] = []
        wheel_y: list[float] = []
        for joint in range(pb.getNumJoints(body, physicsClientId=client)):
            info = pb.getJointInfo(body, joint, physicsClientId=client)
            joint_name = info[1].decode()
            if info[2] != pb.JOINT_REVOLUTE or "wheel" not in joint_name:
                continue
            (self.left if "left" in joint_name else self.right).append(joint)
            wheel_y.append(abs(info[14][1]))  # parentFramePos y: half the track
        if not self.left or not self.right:
            pb.removeBody(body, physicsClientId=client)
            raise SpawnError(f"robot '{name}': husky URDF has no left/right wheel joints")
        self.track = 2.0 * sum(wheel_y) / len(wheel_y)
        self._applied: tuple[float, float] | None = None

    def before_step(self, linear: float, angular: float) -> None:
        # Velocity motors keep their target: only talk to pybullet when the command changes.
        if self._applied == (linear, angular):
            return
        self._applied = (linear, angular)
        spread = angular * self.track / 2 * self.SKID_FACTOR
        left = (linear - spread) / self.WHEEL_RADIUS
        right = (linear + spread) / self.WHEEL_RADIUS
        joints = self.left + self.right
        targets = [left] * len(self.left) + [right] * len(self.right)
        pb.setJointMotorControlArray(
            self.body,
            joints,
            pb.VELOCITY_CONTROL,
            targetVelocities=targets,
            forces=[self.MAX_WHEEL_FORCE] * len(joints),
            physicsClientId=self.client,
        )


class RacecarRobot(_Robot):
    """pybullet_data's racecar URDF: rear-wheel drive, Ackermann steering (it cannot turn on the
    spot: the twist's angular rate is turned into a steering angle for the current speed)."""

    WHEEL_RADIUS = 0.05
    WHEELBASE = 0.325
    MAX_STEER = 0.6  # rad
    MAX_FORCE = 10.0

    def __init__(self, client: int, name: str, model: ModelSpec, pose: Pose2D) -> None:
        body = _load_urdf(client, "racecar/racecar.urdf", pose, 0.0)
        super().__init__(client, name, model, body)
        joints = {
            pb.getJointInfo(body, j, physicsClientId=client)[1].decode(): j
            for j in range(pb.getNumJoints(body, physicsClientId=client))
        }
        self.drive = [j for n, j in joints.items() if n.endswith("wheel_joint")]
        self.steer = [j for n, j in joints.items() if "steering_hinge" in n]
        if not self.drive or not self.steer:
            pb.removeBody(body, physicsClientId=client)
            raise SpawnError(f"robot '{name}': racecar URDF has no wheel or steering joints")
        self._applied: tuple[float, float] | None = None

    def before_step(self, linear: float, angular: float) -> None:
        if self._applied == (linear, angular):
            return
        self._applied = (linear, angular)
        v, w = linear, angular
        steer = 0.0 if abs(v) < 1e-3 else math.atan(w * self.WHEELBASE / v)
        steer = min(max(steer, -self.MAX_STEER), self.MAX_STEER)
        c = self.client
        pb.setJointMotorControlArray(
            self.body,
            self.drive,
            pb.VELOCITY_CONTROL,
            targetVelocities=[v / self.WHEEL_RADIUS] * len(self.drive),
            forces=[self.MAX_FORCE] * len(self.drive),
            physicsClientId=c,
        )
        pb.setJointMotorControlArray(
            self.body, self.steer, pb.POSITION_CONTROL, targetPositions=[steer] * len(self.steer), physicsClientId=c
        )


@dataclass
class ContactEvent:
    sim_time: float
    a: str
    b: str
    kind: str  # "robot-robot" | "robot-obstacle"

    def as_dict(self) -> dict:
        return {"sim_time": round(self.sim_time, 3), "a": self.a, "b": self.b, "kind": self.kind}


class PhysicsWorld:
    def __init__(self, physics_rate: float = 240.0, solver_iterations: int = 10) -> None:
        self.client = pb.connect(pb.DIRECT)
        self.dt = 1.0 / physics_rate
        pb.setAdditionalSearchPath(pybullet_data.getDataPath(), physicsClientId=self.client)
        pb.setTimeStep(self.dt, physicsClientId=self.client)
        self.gravity = 0.0  # switched on while URDF robots (which need it for traction) are present
        self._light_every = slot_steps(physics_rate)  # light velocity refresh, in ticks: once a slot
        self._ticks = 0
        # 10 iterations instead of 50: planar contacts converge fast and the solver dominates the
        # step cost with many bodies.
        pb.setPhysicsEngineParameter(numSolverIterations=solver_iterations, physicsClientId=self.client)
        plane_shape = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=self.client)
        self.plane = pb.createMultiBody(0, plane_shape, physicsClientId=self.client)
        self.robots: dict[str, _Robot] = {}
        self.obstacles: dict[str, tuple[int, ObstacleSpec]] = {}
        self._names: dict[int, tuple[str, str]] = {}  # body id -> (name, "robot"|"obstacle")
        self.sim_time = 0.0
        self._touching: dict[tuple[str, str], float] = {}  # pair -> sim time last seen in contact
        self._light: list[LightRobot] = []
        self._light_rows = np.zeros(0, dtype=np.int64)  # rows of the light robots in poses()
        self._urdf: list[_Robot] = []
        self._urdf_rows: list[int] = []
        self._commands = np.zeros((0, 2))  # (n, 2) linear, angular by row, within the limits below
        self._limits = np.zeros((0, 2))  # (n, 2) max linear and angular speed by row
        self.row: dict[str, int] = {}  # robot name -> its row in poses()
        self._bodies: list[int] = []
        self._com_offsets: np.ndarray | None = None  # (n, 3) _Robot.com_offset by row; None: all zero
        self._poses: tuple[np.ndarray, np.ndarray] | None = None  # positions, quaternions: until the next step

    # -- content ---------------------------------------------------------------------------------

    def add_obstacle(self, spec: ObstacleSpec) -> None:
        c = self.client
        if spec.type == "cylinder":
            shape = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=spec.radius, height=spec.height, physicsClientId=c)
        else:
            half = (spec.size[0] / 2, spec.size[1] / 2, spec.height / 2)
            shape = pb.createCollisionShape(pb.GEOM_BOX, halfExtents=half, physicsClientId=c)
        body = pb.createMultiBody(
            0,
            shape,
            basePosition=(spec.x, spec.y, spec.height / 2),
            baseOrientation=flat_quaternion(spec.yaw),
            physicsClientId=c,
        )
        pb.changeDynamics(body, -1, lateralFriction=0.0, restitution=0.0, physicsClientId=c)
        self.obstacles[spec.name] = (body, spec)
        self._names[body] = (spec.name, "obstacle")

    def remove_obstacle(self, name: str) -> None:
        body, _ = self.obstacles.pop(name)
        self._names.pop(body, None)
        pb.removeBody(body, physicsClientId=self.client)

    def placement_problem(self, name: str, model: ModelSpec, pose: Pose2D) -> str | None:
        """Why a robot cannot be placed at pose (overlaps), or None when the spot is free."""
        obstacles = ((obstacle_name, obstacle_shape(spec)) for obstacle_name, (_, spec) in self.obstacles.items())
        robots = ((other, robot_shape(robot.model, *robot.pose())) for other, robot in self.robots.items())
        return placement_problem(name, robot_shape(model, pose.x, pose.y, pose.yaw), obstacles, robots)

    def add_robot(self, name: str, model: ModelSpec, pose: Pose2D) -> None:
        if name in self.robots:
            raise SpawnError(f"robot '{name}' already exists")
        problem = self.placement_problem(name, model, pose)
        if problem:
            raise SpawnError(problem)
        if model.type == "husky":
            robot: _Robot = HuskyRobot(self.client, name, model, pose)
        elif model.type == "racecar":
            robot = RacecarRobot(self.client, name, model, pose)
        else:
            robot = LightRobot(self.client, name, model, pose, self.plane)
        self.robots[name] = robot
        self._names[robot.body] = (name, "robot")
        self._sort_robots()

    def remove_robot(self, name: str) -> None:
        robot = self.robots.pop(name)
        self._names.pop(robot.body, None)
        pb.removeBody(robot.body, physicsClientId=self.client)
        self._sort_robots()
        self._touching = {pair: t for pair, t in self._touching.items() if name not in pair}

    def _sort_robots(self) -> None:
        self._poses = None
        commands = dict(zip(self.row, self._commands.tolist(), strict=True))
        self.row = {name: i for i, name in enumerate(self.robots)}
        self._commands = np.array([commands.get(name, (0.0, 0.0)) for name in self.row], dtype=float).reshape(-1, 2)
        self._limits = np.array(
            [(r.model.max_linear_speed, r.model.max_angular_speed) for r in self.robots.values()], dtype=float
        ).reshape(-1, 2)
        self._bodies = [robot.body for robot in self.robots.values()]
        offsets = np.array([robot.com_offset for robot in self.robots.values()], dtype=float).reshape(-1, 3)
        self._com_offsets = offsets if offsets.any() else None
        self._light = [r for r in self.robots.values() if isinstance(r, LightRobot)]
        self._light_rows = np.array([self.row[r.name] for r in self._light], dtype=np.int64)
        self._urdf = [r for r in self.robots.values() if not isinstance(r, LightRobot)]
        self._urdf_rows = [self.row[r.name] for r in self._urdf]
        gravity = GRAVITY if self._urdf else 0.0
        if gravity != self.gravity:
            self.gravity = gravity
            pb.setGravity(0, 0, gravity, physicsClientId=self.client)

    def shapes(self) -> tuple[list[Shape], list[str | None]]:
        """Every footprint now, with the robot name owning it (None for obstacles)."""
        shapes: list[Shape] = [obstacle_shape(spec) for _, spec in self.obstacles.values()]
        owners: list[str | None] = [None] * len(shapes)
        for name, robot in self.robots.items():
            x, y, yaw = robot.pose()
            shapes.append(robot_shape(robot.model, x, y, yaw))
            owners.append(name)
        return shapes, owners

    # -- running ---------------------------------------------------------------------------------

    def command(self, name: str, linear: float, angular: float) -> None:
        row = self.row[name]
        self._commands[row] = np.clip((linear, angular), -self._limits[row], self._limits[row])

    def command_all(self, commands: np.ndarray) -> None:
        """(n, 2) linear and angular speed of every robot, by row."""
        self._commands = np.clip(commands, -self._limits, self._limits)

    def step(self) -> None:
        dt, gravity = self.dt, self.gravity
        # Light robots are driven on the tick after every _light_every-th one: the world's own
        # 60 Hz work (lidar, contacts) has just read the poses those ticks, so they are read once.
        if self._light and (gravity or self._ticks % self._light_every == 0):
            self._drive_light(dt, gravity)
        self._ticks += 1
        if self._urdf:
            commands = self._commands.tolist()
            for urdf_robot, row in zip(self._urdf, self._urdf_rows, strict=True):
                urdf_robot.before_step(*commands[row])
        pb.stepSimulation(physicsClientId=self.client)
        self._poses = None
        self.sim_time += dt

    def _drive_light(self, dt: float, gravity: float) -> None:
        """Set every light robot's velocity from its heading and command, first putting back flat
        any that a contact tilted or lifted (rare, so cheap)."""
        client = self.client
        positions, quaternions = self._raw_poses()
        positions, quaternions = positions[self._light_rows], quaternions[self._light_rows]
        yaws = _yaws(quaternions)
        tilted = (np.abs(quaternions[:, 0]) + np.abs(quaternions[:, 1]) > 1e-4) | (
            np.abs(positions[:, 2] - LIGHT_Z) > 1e-3
        )
        for i in np.flatnonzero(tilted).tolist():
            x, y, _ = positions[i].tolist()
            pb.resetBasePositionAndOrientation(
                self._light[i].body, (x, y, LIGHT_Z), flat_quaternion(float(yaws[i])), physicsClientId=client
            )
        if tilted.any():
            self._poses = None
        speeds, turns = self._commands[self._light_rows].T
        vx, vy = (speeds * np.cos(yaws)).tolist(), (speeds * np.sin(yaws)).tolist()
        vz = -gravity * dt
        reset = pb.resetBaseVelocity
        for robot, x, y, turn in zip(self._light, vx, vy, turns.tolist(), strict=True):
            reset(robot.body, (x, y, vz), (0.0, 0.0, turn), physicsClientId=client)

    def _raw_poses(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (n, 3) and quaternions (n, 4) of every robot, read once per step."""
        if self._poses is None:
            get, client = pb.getBasePositionAndOrientation, self.client
            read = [get(body, physicsClientId=client) for body in self._bodies]
            positions = np.array([position for position, _ in read], dtype=float).reshape(-1, 3)
            quaternions = np.array([orientation for _, orientation in read], dtype=float).reshape(-1, 4)
            if self._com_offsets is not None:
                positions = _frame_positions(positions, quaternions, self._com_offsets)
            self._poses = (positions, quaternions)
        return self._poses

    def poses(self) -> np.ndarray:
        """(n, 3) x, y, yaw of every robot, row `self.row[name]`."""
        positions, quaternions = self._raw_poses()
        return np.column_stack((positions[:, 0], positions[:, 1], _yaws(quaternions)))

    def velocities(self, rows: np.ndarray, yaws: np.ndarray) -> np.ndarray:
        """(S, 3) linear, lateral and angular velocity of the robots in `rows` (body frame), whose
        headings are `yaws`."""
        get, client, bodies = pb.getBaseVelocity, self.client, self._bodies
        read = [get(bodies[row], physicsClientId=client) for row in rows.tolist()]
        world = np.array([(v[0], v[1], w[2]) for v, w in read], dtype=float).reshape(-1, 3)
        if self._com_offsets is not None:  # the frame's velocity: the centre of mass's minus w x r
            spin = np.array([w for _, w in read], dtype=float).reshape(-1, 3)
            arm = _rotated(self._raw_poses()[1][rows], self._com_offsets[rows])
            world[:, :2] -= np.cross(spin, arm)[:, :2]
        c, s = np.cos(yaws), np.sin(yaws)
        return np.column_stack((c * world[:, 0] + s * world[:, 1], -s * world[:, 0] + c * world[:, 1], world[:, 2]))

    def state(self, name: str) -> RobotState:
        return self.robots[name].state()

    def poll_contacts(self, debounce: float = 0.1) -> list[ContactEvent]:
        """New robot-robot and robot-obstacle contacts since the last call.

        A pair counts once when it starts touching; it has to be apart for `debounce` seconds of
        sim time before touching again counts as a new contact (bodies pressed together flicker
        in and out of contact from one step to the next).
        """
        now = self.sim_time
        names = self._names
        seen: set[tuple[str, str]] = set()
        kinds: dict[tuple[str, str], str] = {}
        for point in pb.getContactPoints(physicsClientId=self.client):
            a, b = names.get(point[1]), names.get(point[2])
            if a is None or b is None or (a[1] != "robot" and b[1] != "robot"):
                continue  # the ground, or a body removed meanwhile
            pair = (a[0], b[0]) if a[0] < b[0] else (b[0], a[0])
            seen.add(pair)
            kinds[pair] = "robot-robot" if a[1] == b[1] else "robot-obstacle"
        events = []
        for pair in seen:
            last = self._touching.get(pair)
            if last is None or now - last > debounce:
                events.append(ContactEvent(now, pair[0], pair[1], kinds[pair]))
            self._touching[pair] = now
        self._touching = {pair: t for pair, t in self._touching.items() if now - t <= debounce}
        events.sort(key=lambda e: (e.a, e.b))
        return events

    def close(self) -> None:
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = None
