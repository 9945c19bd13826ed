"""2D footprints and overlap tests (pure).  The world is planar: robots and obstacles are circles
or oriented rectangles seen from above; heights only matter to pybullet."""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

from fleet.world.description import ModelSpec, ObstacleSpec, WorldSpec

SPAWN_MARGIN = 0.02  # m of clearance required around a new robot


@dataclass(frozen=True)
class Shape:
    kind: str  # "circle" | "rect"
    x: float
    y: float
    yaw: float = 0.0
    radius: float = 0.0  # circle
    half_x: float = 0.0  # rect
    half_y: float = 0.0

    @property
    def bounding_radius(self) -> float:
        return self.radius if self.kind == "circle" else math.hypot(self.half_x, self.half_y)


def obstacle_shape(obstacle: ObstacleSpec) -> Shape:
    if obstacle.type == "cylinder":
        return Shape("circle", obstacle.x, obstacle.y, obstacle.yaw, radius=obstacle.radius)
    return Shape("rect", obstacle.x, obstacle.y, obstacle.yaw, half_x=obstacle.size[0] / 2, half_y=obstacle.size[1] / 2)


def robot_shape(model: ModelSpec, x: float, y: float, yaw: float) -> Shape:
    if model.is_round:
        return Shape("circle", x, y, yaw, radius=model.radius)
    return Shape("rect", x, y, yaw, half_x=model.length / 2, half_y=model.width / 2)


def _to_local(shape: Shape, x: float, y: float) -> tuple[float, float]:
    c, s = math.cos(shape.yaw), math.sin(shape.yaw)
    dx, dy = x - shape.x, y - shape.y
    return c * dx + s * dy, -s * dx + c * dy


def _corners(shape: Shape) -> list[tuple[float, float]]:
    c, s = math.cos(shape.yaw), math.sin(shape.yaw)
    out = []
    for sx, sy in ((1, 1), (-1, 1), (-1, -1), (1, -1)):
        lx, ly = sx * shape.half_x, sy * shape.half_y
        out.append((shape.x + c * lx - s * ly, shape.y + s * lx + c * ly))
    return out


def overlaps(a: Shape, b: Shape, margin: float = 0.0) -> bool:
    """True when the two footprints, each grown by margin/2, intersect."""
    if math.hypot(a.x - b.x, a.y - b.y) >= a.bounding_radius + b.bounding_radius + margin:
        return False
    if a.kind == "circle" and b.kind == "circle":
        return True  # the bounding test above is exact for circles
    if a.kind == "rect" and b.kind == "circle":
        a, b = b, a
    if a.kind == "circle":  # circle against rectangle: nearest point of the rectangle
        lx, ly = _to_local(b, a.x, a.y)
        nx = min(max(lx, -b.half_x), b.half_x)
        ny = min(max(ly, -b.half_y), b.half_y)
        return math.hypot(lx - nx, ly - ny) < a.radius + margin
    # two rectangles: separating axis theorem on the four edge normals
    corners_a, corners_b = _corners(a), _corners(b)
    for yaw in (a.yaw, a.yaw + math.pi / 2, b.yaw, b.yaw + math.pi / 2):
        ax, ay = math.cos(yaw), math.sin(yaw)
        pa = [ax * px + ay * py for px, py in corners_a]
        pb = [ax * px + ay * py for px, py in corners_b]
        if max(pa) + margin <= min(pb) or max(pb) + margin <= min(pa):
            return False
    return True


def placement_problem(
    name: str, shape: Shape, obstacles: Iterable[tuple[str, Shape]], robots: Iterable[tuple[str, Shape]]
) -> str | None:
    """Why the world refuses to spawn robot `name` with footprint `shape` among these obstacles
    and robots (name, footprint), or None when the spot is free.  The world asks this before each
    spawn, and `fleet render` asks it of every robot of a spec, so both refuse the same poses."""
    for obstacle_name, other in obstacles:
        if overlaps(shape, other, SPAWN_MARGIN):
            return f"spawn pose ({shape.x:g}, {shape.y:g}) of robot '{name}' overlaps obstacle '{obstacle_name}'"
    for other_name, other in robots:
        if other_name != name and overlaps(shape, other, SPAWN_MARGIN):
            return (
                f"spawn pose ({shape.x:g}, {shape.y:g}) of robot '{name}' overlaps robot "
                f"'{other_name}' at ({other.x:.2f}, {other.y:.2f})"
            )
    return None


def spawn_problem(world: WorldSpec) -> tuple[int, str] | None:
    """The first robot of `world` the world would refuse to spawn, as (its index, why), or None.

    The world spawns robots in order, each where nothing spawned before it is.  Robots are put in
    a grid of cells as wide as two of the largest robots, so each is checked against the few in
    its own and the eight neighbouring cells: linear in robots, where all pairs would be quadratic."""
    obstacles = [(obstacle.name, obstacle_shape(obstacle)) for obstacle in world.obstacles]
    shapes = [robot_shape(robot.model, robot.pose.x, robot.pose.y, robot.pose.yaw) for robot in world.robots]
    cell = 2 * max((shape.bounding_radius for shape in shapes), default=1.0) + SPAWN_MARGIN
    grid: dict[tuple[int, int], list[tuple[str, Shape]]] = {}
    for index, (robot, shape) in enumerate(zip(world.robots, shapes, strict=True)):
        column, row = math.floor(shape.x / cell), math.floor(shape.y / cell)
        near = [placed for dx in (-1, 0, 1) for dy in (-1, 0, 1) for placed in grid.get((column + dx, row + dy), ())]
        problem = placement_problem(robot.name, shape, obstacles, near)
        if problem is not None:
            return index, problem
        grid.setdefault((column, row), []).append((robot.name, shape))
    return None
