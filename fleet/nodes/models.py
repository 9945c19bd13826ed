"""The decisions the nodes make, as plain functions and classes with no ROS in them.

Keeping these apart from the rclpy glue lets the tests check the steering law, the battery model
and the safety gate in microseconds, and lets the node modules stay thin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# Steering gains.  Turning: the commanded rate is proportional to the heading error and capped by
# max_turn_rate.  Driving: speed falls with the cosine of the heading error (zero beyond 90
# degrees, so the robot turns in place rather than driving away from the goal) and near the goal
# is capped at APPROACH_GAIN * distance, so a high max_speed cannot overshoot a small tolerance.
TURN_GAIN = 2.0  # rad/s per rad of heading error
APPROACH_GAIN = 2.0  # m/s per m of remaining distance


def wrap_angle(angle: float) -> float:
    """The same angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Heading (rotation about z) of a quaternion; roll and pitch are ignored (planar robots)."""
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def pairs(flat: Sequence[float]) -> list[tuple[float, float]]:
    """[x0, y0, x1, y1, ...] -> [(x0, y0), (x1, y1), ...]; the node checked the length
    (fleet.nodes.parameters.CONTROLLER_RULES)."""
    return [(float(flat[i]), float(flat[i + 1])) for i in range(0, len(flat) - 1, 2)]


def steer(
    x: float,
    y: float,
    yaw: float,
    goal: tuple[float, float],
    max_speed: float,
    max_turn_rate: float,
) -> tuple[float, float]:
    """Forward speed and turn rate that bring a planar robot at (x, y, yaw) towards goal."""
    dx, dy = goal[0] - x, goal[1] - y
    distance = math.hypot(dx, dy)
    error = wrap_angle(math.atan2(dy, dx) - yaw)
    turn = max(-max_turn_rate, min(max_turn_rate, TURN_GAIN * error))
    speed = min(max_speed * max(0.0, math.cos(error)), APPROACH_GAIN * distance)
    return speed, turn


@dataclass
class WaypointFollower:
    """Which waypoint is the goal; advances within tolerance, loops or finishes at the end."""

    waypoints: list[tuple[float, float]]
    loop: bool = True
    index: int = 0
    laps: int = 0
    finished: bool = False

    def set_waypoints(self, waypoints: list[tuple[float, float]]) -> None:
        # A new route starts from its first waypoint: an old index means nothing in a new list.
        self.waypoints = waypoints
        self.index, self.laps, self.finished = 0, 0, False

    def set_loop(self, loop: bool) -> None:
        self.loop = loop
        if loop and self.finished:  # switching loop on resumes a finished route
            self.finished, self.index, self.laps = False, 0, self.laps + 1

    @property
    def goal(self) -> tuple[float, float]:
        return self.waypoints[self.index]

    def update(self, x: float, y: float, tolerance: float) -> float:
        """Advance past every waypoint already within tolerance; distance to the current goal."""
        # Bounded by the list length so a route of identical points cannot spin forever.
        for _ in range(len(self.waypoints)):
            distance = math.hypot(self.goal[0] - x, self.goal[1] - y)
            if self.finished or distance > tolerance:
                return distance
            if self.index + 1 < len(self.waypoints):
                self.index += 1
            elif self.loop:
                self.index, self.laps = 0, self.laps + 1
            else:
                self.finished = True
        return math.hypot(self.goal[0] - x, self.goal[1] - y)


@dataclass
class BatteryModel:
    """Energy bookkeeping: idle draw plus a draw proportional to speed, integrated over time.

    Speed is held constant between samples (piecewise constant), so the drained energy is exact
    for the sampled speeds whatever the publish rate.
    """

    capacity_wh: float
    energy_wh: float
    idle_draw_w: float
    motion_draw_w_per_mps: float
    speed: float = 0.0

    @property
    def fraction(self) -> float:
        return max(0.0, min(1.0, self.energy_wh / self.capacity_wh))

    @property
    def draw_w(self) -> float:
        return self.idle_draw_w + self.motion_draw_w_per_mps * abs(self.speed)

    def advance(self, seconds: float) -> None:
        if seconds > 0.0:
            self.energy_wh = max(0.0, self.energy_wh - self.draw_w * seconds / 3600.0)


def battery_health(fraction: float, low: float, critical: float) -> str:
    """'dead' below critical, 'low' below low, else 'good'."""
    if fraction < critical:
        return "dead"
    if fraction < low:
        return "low"
    return "good"


def nearest_in_cone(
    ranges: Sequence[float],
    angle_min: float,
    angle_increment: float,
    range_min: float,
    range_max: float,
    half_angle: float,
) -> float:
    """Closest valid return within +-half_angle of straight ahead (inf when there is none)."""
    r = np.asarray(ranges, dtype=float)
    if r.size == 0:
        return math.inf
    angles = angle_min + angle_increment * np.arange(r.size)
    # Wrap so scans given as 0..2pi and as -pi..pi both put "ahead" at 0.
    angles = (angles + np.pi) % (2.0 * np.pi) - np.pi
    # REP-117: -inf means something closer than range_min, the most urgent obstacle there is.
    r = np.where(np.isneginf(r), range_min, r)
    # Other returns outside [range_min, range_max] (+inf = nothing hit, nan = invalid) are not obstacles.
    valid = np.isfinite(r) & (r >= range_min) & (r <= range_max) & (np.abs(angles) <= half_angle)
    return float(r[valid].min()) if valid.any() else math.inf


def gate_forward(linear_x: float, nearest_ahead: float, safety_distance: float) -> float:
    """Forward speed allowed with an obstacle nearest_ahead metres in front; reversing stays."""
    if linear_x > 0.0 and nearest_ahead < safety_distance:
        return 0.0
    return linear_x
