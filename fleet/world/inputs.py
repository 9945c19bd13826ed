"""What the robots' nodes send the world, as the physics side sees it: one snapshot of arrays by
physics row, taken by the ROS side (fleet.world.ros_bridge) and read by the loop (fleet.world.app).

No rclpy here: the physics process reads these without loading ROS.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

# Columns of RobotInputs.commands
LINEAR, ANGULAR, WALL, SIM = range(4)
NEVER = -math.inf  # the receive time of a command that never came


# A battery reading older than this (wall seconds) is no reading: the robot's battery node was
# removed (`enable_battery: false`) or stopped.  Its slowest rate is 0.1 Hz of the node's clock, a
# 10 s period, 20 s at half real time: a reading is not stale before two such periods have passed.
BATTERY_STALE = 45.0


def fresh_battery(readings: list[tuple[float, float]], now: float) -> np.ndarray:
    """(percentage, time.monotonic() when received) of every row -> the percentages, nan for a
    row with no reading or a stale one."""
    values = np.array([value for value, _ in readings], dtype=float)
    received = np.array([at for _, at in readings], dtype=float)
    return np.where(now - received <= BATTERY_STALE, values, math.nan)


@dataclass(frozen=True)
class RobotInputs:
    """The latest inputs of every robot of one layout (`generation`), by row."""

    generation: int
    commands: np.ndarray  # (n, 4): linear, angular, time.monotonic() and sim time when received
    battery: np.ndarray  # (n,): percentage, nan when none was received
    odom_subscribers: np.ndarray  # (n,): subscriptions matched to the robot's odom

    @staticmethod
    def empty(generation: int, robots: int) -> RobotInputs:
        commands = np.zeros((robots, 4))
        commands[:, WALL:] = NEVER
        return RobotInputs(generation, commands, np.full(robots, np.nan), np.zeros(robots, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.battery)

    def remapped(self, old: list[str], new: list[str], generation: int) -> RobotInputs:
        """These inputs, of the robots `old` by row, rearranged for the robots `new` by row (robots
        new to them: no inputs yet; inputs that are not of `old`: none at all)."""
        fresh = RobotInputs.empty(generation, len(new))
        if len(self) != len(old):
            return fresh
        where = {name: row for row, name in enumerate(old)}
        pairs = [(row, where[name]) for row, name in enumerate(new) if name in where]
        if pairs:
            to, source = (np.array(side, dtype=np.int64) for side in zip(*pairs, strict=True))
            fresh.commands[to] = self.commands[source]
            fresh.battery[to] = self.battery[source]
            fresh.odom_subscribers[to] = self.odom_subscribers[source]
        return fresh

    def live_commands(self, timeouts: np.ndarray, sim_time: float) -> np.ndarray:
        """(n, 2) linear and angular speed: each robot's latest command, or zero once it is older
        than its cmd_timeout in both sim and wall time (a sim-time-only timeout would stop a
        wall-clock publisher in a faster-than-real-time world; a wall-only one would let a stalled
        controller drive on in a slow world)."""
        commands = self.commands
        expired = (sim_time - commands[:, SIM] > timeouts) & (time.monotonic() - commands[:, WALL] > timeouts)
        return np.where(expired[:, None], 0.0, commands[:, :2])

    def battery_of(self, row: int) -> float | None:
        value = float(self.battery[row])
        return None if math.isnan(value) else value

    def link(self, row: int) -> dict[str, float | int | None]:
        """What says a robot's data flows: the age of its last command (wall seconds, None: never
        received) and the subscriptions matched to its odom (its nodes, once discovered)."""
        wall = float(self.commands[row, WALL])
        return {
            # max(): a command stamped in the future (a benchmark's "never expires") is fresh
            "cmd_age": None if wall == NEVER else round(max(0.0, time.monotonic() - wall), 2),
            "odom_subscribers": int(self.odom_subscribers[row]),
        }
