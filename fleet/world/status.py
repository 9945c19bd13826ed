"""The world's status file: building the JSON document, writing it atomically, reading it back.

The document is plain JSON data; the agent running the world serves it as is over the control
plane (fleet.wire.protocol.WorldDocument validates it) and cuts it down for status replies:

    {"fleet", "sim_time", "wall_time", "real_time_factor", "physics_rate",
     "robots": {name: {"pose": {"x", "y", "yaw"}, "spawn": {"x", "y", "yaw"} (its pose in world.yaml),
                       "velocity": {"linear", "angular"},
                       "battery": fraction 0..1 or null, "model": {"type", "radius" | "length", "width"},
                       "trail": [[x, y], ...], "scan_hits": [[x, y], ...],
                       "cmd_age": s since its last cmd_vel or null, "odom_subscribers": n}},
     "obstacles": [{"name", "type": "box"|"cylinder", "position": [x, y], "yaw", "size": [lx, ly, h] | "radius"}],
     "contacts": {"count", "last": [{"sim_time", "a", "b", "kind"}]},
     "errors": [{"sim_time", "message"}]}
"""

from __future__ import annotations

import json
import math
from collections import deque
from pathlib import Path
from typing import Any

from fleet.files import write_atomic
from fleet.world.description import ModelSpec, ObstacleSpec, Pose2D

TRAIL_LENGTH = 60  # poses kept per robot
TRAIL_PERIOD = 0.5  # s of sim time between trail points
SCAN_HITS_MAX = 90  # lidar hit points kept per robot (decimated)
CONTACTS_KEPT = 20


def model_dict(model: ModelSpec) -> dict[str, Any]:
    if model.is_round:
        return {"type": model.type, "radius": model.radius}
    return {"type": model.type, "length": model.length, "width": model.width}


def obstacle_dict(spec: ObstacleSpec) -> dict[str, Any]:
    entry: dict[str, Any] = {"name": spec.name, "type": spec.type, "position": [spec.x, spec.y], "yaw": spec.yaw}
    if spec.type == "cylinder":
        entry.update(radius=spec.radius, height=spec.height)
    else:
        entry["size"] = list(spec.size)
    return entry


class Trail:
    """A short history of positions, sampled every TRAIL_PERIOD of sim time."""

    def __init__(self) -> None:
        self.points: deque[tuple[float, float]] = deque(maxlen=TRAIL_LENGTH)
        self.next_time = 0.0

    def sample(self, sim_time: float, x: float, y: float) -> None:
        if sim_time >= self.next_time:
            self.points.append((round(x, 3), round(y, 3)))
            self.next_time = sim_time + TRAIL_PERIOD


def finish_status(parts: dict[str, Any]) -> dict[str, Any]:
    """The status document from the world's parts: each robot's "trail" (points) and "hits"
    ((x, y, yaw, angle_min, angle_increment, ranges) of its latest scan, or None) become the
    "trail" and the decimated "scan_hits" of the document."""
    from fleet.world.lidar import beam_angles, hit_points

    robots = {}
    for name, entry in parts["robots"].items():
        robot = {key: value for key, value in entry.items() if key != "hits"}
        robot["trail"] = [list(point) for point in entry["trail"]]
        points: list[tuple[float, float]] = []
        if entry["hits"] is not None:
            x, y, yaw, angle_min, increment, ranges = entry["hits"]
            angles = beam_angles(angle_min, increment, len(ranges))
            points = hit_points(x, y, yaw, angles, ranges, max(1, math.ceil(len(ranges) / SCAN_HITS_MAX)))
        robot["scan_hits"] = [list(point) for point in points]
        robots[name] = robot
    return {**parts, "robots": robots}


def write_status(path: str | Path, data: dict[str, Any]) -> None:
    """Readers see the old status or the new one, never half of one."""
    # json.dumps uses the C encoder; json.dump(data, file) streams through the pure-Python one
    # (measured 10x slower on a 100-robot status).
    write_atomic(path, json.dumps(data, separators=(",", ":"), allow_nan=False))


def read_status(path: str | Path) -> dict[str, Any] | None:
    """The status document, or None when missing or unreadable (a crash cannot leave a half file,
    but a user may have edited it)."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError, RecursionError):  # RecursionError: JSON nested too deeply
        return None
    return data if isinstance(data, dict) else None


def written_since(status: dict[str, Any], started_at: float | None) -> bool:
    """Whether the world process started at `started_at` (wall time, None: none running) wrote
    this document.  The file outlives its writer (a restarted world resumes from it), so until a
    new world writes its first status, the file still tells of the previous one."""
    wall_time = status.get("wall_time")
    if started_at is None or isinstance(wall_time, bool) or not isinstance(wall_time, int | float):
        return True  # nothing to tell them apart: a stopped world's last word is still its state
    return wall_time >= started_at


def last_sim_time(status: dict[str, Any] | None) -> float:
    """The sim time a status document reports (0 when missing or not a finite time >= 0)."""
    value = (status or {}).get("sim_time")
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) or value < 0:
        return 0.0
    return float(value)


def pose_dict(pose: Pose2D) -> dict[str, float]:
    return {"x": pose.x, "y": pose.y, "yaw": pose.yaw}


def last_poses(status: dict[str, Any] | None, spawn: dict[str, Pose2D]) -> dict[str, Pose2D]:
    """Robot poses reported in a status document, for the robots whose spawn pose then was
    `spawn[name]`: one given a new spawn pose since starts there (bad entries skipped)."""
    poses: dict[str, Pose2D] = {}
    robots = (status or {}).get("robots")
    if not isinstance(robots, dict):
        return poses
    for name, entry in robots.items():
        try:
            if name in spawn and "spawn" in entry and _pose(entry["spawn"]) != spawn[name]:
                continue
            poses[name] = _pose(entry["pose"])
        except (KeyError, TypeError, ValueError):
            continue
    return poses


def _pose(entry: Any) -> Pose2D:
    return Pose2D(float(entry["x"]), float(entry["y"]), float(entry["yaw"]))
