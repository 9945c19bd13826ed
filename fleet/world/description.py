"""world.yaml -> frozen dataclasses, validated (pure: no pybullet, no ROS).

Every problem is a WorldError (a FleetError) naming the file, line and column of the offending
value, so `fleet world` can print one line and exit 2.  The YAML is read by fleet's one loader
(fleet.spec.yaml_source: its limits, and the place of every value).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fleet.errors import FleetError, Location, SpecError
from fleet.spec.yaml_source import SourceMap, load_yaml, read_input

NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
MODEL_TYPES = ("light", "husky", "racecar")
# Footprint rectangles (length along x, width) of the URDF models, measured from their URDFs.
URDF_FOOTPRINTS = {"husky": (0.99, 0.68), "racecar": (0.55, 0.30)}
OBSTACLE_TYPES = ("box", "wall", "cylinder")


class WorldError(FleetError):
    """world.yaml is unreadable or invalid."""


@dataclass(frozen=True)
class Pose2D:
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0


@dataclass(frozen=True)
class ModelSpec:
    type: str = "light"
    radius: float = 0.2  # light: footprint circle (other models ignore it)
    length: float = 0.99  # URDF models: footprint rectangle (along x)
    width: float = 0.68
    max_linear_speed: float = 1.0
    max_angular_speed: float = 2.5

    @property
    def is_round(self) -> bool:
        return self.type == "light"

    @property
    def bounding_radius(self) -> float:
        if self.is_round:
            return self.radius
        return math.hypot(self.length, self.width) / 2.0


@dataclass(frozen=True)
class LidarSpec:
    beams: int = 360
    rate: float = 10.0
    range_min: float = 0.12
    range_max: float = 8.0
    angle_min: float = -math.pi
    angle_max: float = math.pi  # exclusive for a full circle (the last beam is angle_max - step)

    @property
    def full_circle(self) -> bool:
        return abs((self.angle_max - self.angle_min) - 2 * math.pi) < 1e-6

    @property
    def increment(self) -> float:
        span = self.angle_max - self.angle_min
        # A full circle must not repeat its first beam; a partial fan includes both ends.
        return span / self.beams if self.full_circle else span / max(self.beams - 1, 1)


@dataclass(frozen=True)
class RobotSpec:
    name: str
    namespace: str
    model: ModelSpec = field(default_factory=ModelSpec)
    pose: Pose2D = field(default_factory=Pose2D)
    lidar: LidarSpec = field(default_factory=LidarSpec)
    odom_rate: float = 50.0
    cmd_timeout: float = 0.5
    ground_truth: bool = False

    def same_except_pose(self, other: RobotSpec) -> bool:
        """True when a reload changed nothing but the initial pose (which only matters at spawn)."""
        return self == RobotSpec(**{**other.__dict__, "pose": self.pose})


@dataclass(frozen=True)
class ObstacleSpec:
    name: str
    type: str  # "box" or "cylinder" (a wall is a box)
    x: float
    y: float
    yaw: float = 0.0
    size: tuple[float, float, float] = (1.0, 1.0, 1.0)  # box: length (x), width (y), height
    radius: float = 0.0  # cylinder
    height: float = 1.0


@dataclass(frozen=True)
class WorldSpec:
    fleet: str = "fleet"
    physics_rate: float = 240.0
    real_time: bool = True
    clock_rate: float = 100.0
    obstacles: tuple[ObstacleSpec, ...] = ()
    robots: tuple[RobotSpec, ...] = ()
    source: str | None = None


# -- YAML nodes with their positions -------------------------------------------------------------


class _Value:
    """A loaded YAML value, and where to ask for the place it was written (only errors ask)."""

    __slots__ = ("path", "places", "value")

    def __init__(self, value: Any, path: tuple = (), places: SourceMap | None = None) -> None:
        self.value = value
        self.path = path
        self.places = places

    def location(self, file: str) -> Location:
        return self.places.locate(self.path) if self.places is not None else Location(file)


def _wrap(value: Any, path: tuple, places: SourceMap) -> _Value:
    if isinstance(value, dict):
        value = {str(key): _wrap(item, (*path, key), places) for key, item in value.items()}
    elif isinstance(value, list):
        value = [_wrap(item, (*path, index), places) for index, item in enumerate(value)]
    return _Value(value, path, places)


class _Reader:
    """Typed access to a converted mapping, raising WorldError with the location."""

    def __init__(self, source: str, node: _Value, what: str) -> None:
        self.source = source
        self.node = node
        self.what = what
        if not isinstance(node.value, dict):
            self.fail(node, f"{what} must be a mapping")
        self.data: dict[str, _Value] = node.value

    def fail(self, node: _Value | None, message: str):
        node = node or self.node
        raise WorldError(message, node.location(self.source))

    def check_keys(self, allowed: set[str]) -> None:
        for key, value in self.data.items():
            if key not in allowed:
                self.fail(value, f"unknown key '{key}' in {self.what} (allowed: {', '.join(sorted(allowed))})")

    def raw(self, key: str) -> _Value | None:
        return self.data.get(key)

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        minimum: float | None = None,
        positive: bool = False,
        maximum: float | None = None,
    ) -> float:
        node = self.data.get(key)
        if node is None or node.value is None:
            if default is None:
                self.fail(None, f"{self.what}: missing '{key}'")
            return float(default)
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            self.fail(node, f"{self.what}: '{key}' must be a number, got {value!r}")
        if positive and value <= 0:
            self.fail(node, f"{self.what}: '{key}' must be > 0, got {value}")
        if minimum is not None and value < minimum:
            self.fail(node, f"{self.what}: '{key}' must be >= {minimum}, got {value}")
        if maximum is not None and value > maximum:
            self.fail(node, f"{self.what}: '{key}' must be <= {maximum}, got {value}")
        return float(value)

    def integer(self, key: str, default: int, *, minimum: int, maximum: int) -> int:
        node = self.data.get(key)
        if node is None:
            return default
        if isinstance(node.value, bool) or not isinstance(node.value, int):
            self.fail(node, f"{self.what}: '{key}' must be an integer, got {node.value!r}")
        if not minimum <= node.value <= maximum:
            self.fail(node, f"{self.what}: '{key}' must be in {minimum}..{maximum}, got {node.value}")
        return node.value

    def boolean(self, key: str, default: bool) -> bool:
        node = self.data.get(key)
        if node is None:
            return default
        if not isinstance(node.value, bool):
            self.fail(node, f"{self.what}: '{key}' must be true or false, got {node.value!r}")
        return node.value

    def string(self, key: str, default: str | None = None) -> str:
        node = self.data.get(key)
        if node is None or node.value is None:
            if default is None:
                self.fail(None, f"{self.what}: missing '{key}'")
            return default
        if not isinstance(node.value, str):
            self.fail(node, f"{self.what}: '{key}' must be a string, got {node.value!r}")
        return node.value

    def name(self, key: str = "name") -> str:
        value = self.string(key)
        if not NAME_RE.match(value):
            self.fail(
                self.data[key],
                f"{self.what}: '{value}' is not a valid name "
                "(letters, digits and underscores, not starting with a digit)",
            )
        return value

    def sub(self, key: str) -> _Reader:
        node = self.data.get(key)
        if node is None:
            return _Reader(self.source, _Value({}), f"{self.what}.{key}")
        return _Reader(self.source, node, f"{self.what}.{key}")

    def numbers(self, key: str, count: int, default: tuple[float, ...] | None = None) -> tuple[float, ...]:
        node = self.data.get(key)
        if node is None:
            if default is None:
                self.fail(None, f"{self.what}: missing '{key}'")
            return default
        items = node.value
        if not isinstance(items, list) or len(items) != count:
            self.fail(node, f"{self.what}: '{key}' must be a list of {count} numbers")
        out = []
        for item in items:
            if (
                isinstance(item.value, bool)
                or not isinstance(item.value, (int, float))
                or not math.isfinite(item.value)
            ):
                self.fail(item, f"{self.what}: '{key}' must contain numbers, got {item.value!r}")
            out.append(float(item.value))
        return tuple(out)


# -- the schema ----------------------------------------------------------------------------------


def _model(reader: _Reader) -> ModelSpec:
    reader.check_keys({"type", "radius", "length", "width", "max_linear_speed", "max_angular_speed"})
    kind = reader.string("type", "light")
    if kind not in MODEL_TYPES:
        reader.fail(reader.raw("type"), f"{reader.what}: unknown model type '{kind}' (known: {', '.join(MODEL_TYPES)})")
    length, width = URDF_FOOTPRINTS.get(kind, (0.99, 0.68))
    return ModelSpec(
        type=kind,
        radius=reader.number("radius", 0.2, positive=True, maximum=5.0),
        length=reader.number("length", length, positive=True, maximum=10.0),
        width=reader.number("width", width, positive=True, maximum=10.0),
        max_linear_speed=reader.number("max_linear_speed", 1.0, minimum=0.0, maximum=20.0),
        max_angular_speed=reader.number("max_angular_speed", 2.5, minimum=0.0, maximum=50.0),
    )


def _lidar(reader: _Reader) -> LidarSpec:
    reader.check_keys({"beams", "rate", "range_min", "range_max", "angle_min", "angle_max"})
    lidar = LidarSpec(
        beams=reader.integer("beams", 360, minimum=1, maximum=10000),
        rate=reader.number("rate", 10.0, positive=True, maximum=1000.0),
        range_min=reader.number("range_min", 0.12, minimum=0.0),
        range_max=reader.number("range_max", 8.0, positive=True, maximum=1000.0),
        angle_min=reader.number("angle_min", -math.pi, minimum=-2 * math.pi),
        angle_max=reader.number("angle_max", math.pi, maximum=2 * math.pi),
    )
    if lidar.range_min >= lidar.range_max:
        reader.fail(reader.raw("range_min"), f"{reader.what}: range_min must be below range_max")
    if lidar.angle_min >= lidar.angle_max or lidar.angle_max - lidar.angle_min > 2 * math.pi + 1e-9:
        reader.fail(reader.raw("angle_min"), f"{reader.what}: need angle_min < angle_max spanning at most 2*pi")
    return lidar


def _pose(reader: _Reader) -> Pose2D:
    reader.check_keys({"x", "y", "yaw"})
    return Pose2D(reader.number("x", 0.0), reader.number("y", 0.0), reader.number("yaw", 0.0))


def _robot(reader: _Reader) -> RobotSpec:
    reader.check_keys({"name", "namespace", "model", "pose", "lidar", "odom_rate", "cmd_timeout", "ground_truth"})
    name = reader.name()
    reader.what = f"robot '{name}'"
    namespace = reader.string("namespace", f"/{name}")
    if not namespace.startswith("/"):
        namespace = "/" + namespace
    namespace = namespace.rstrip("/") or "/"
    if namespace != "/" and not all(NAME_RE.match(part) for part in namespace[1:].split("/")):
        reader.fail(reader.raw("namespace"), f"{reader.what}: '{namespace}' is not a valid ROS namespace")
    return RobotSpec(
        name=name,
        namespace=namespace,
        model=_model(reader.sub("model")),
        pose=_pose(reader.sub("pose")),
        lidar=_lidar(reader.sub("lidar")),
        odom_rate=reader.number("odom_rate", 50.0, positive=True, maximum=1000.0),
        cmd_timeout=reader.number("cmd_timeout", 0.5, positive=True, maximum=3600.0),
        ground_truth=reader.boolean("ground_truth", False),
    )


def _obstacle(reader: _Reader) -> ObstacleSpec:
    reader.check_keys({"name", "type", "position", "yaw", "size", "radius", "height"})
    name = reader.name()
    reader.what = f"obstacle '{name}'"
    kind = reader.string("type")
    if kind not in OBSTACLE_TYPES:
        reader.fail(reader.raw("type"), f"{reader.what}: unknown type '{kind}' (known: {', '.join(OBSTACLE_TYPES)})")
    x, y = reader.numbers("position", 2)
    yaw = reader.number("yaw", 0.0)
    if kind == "cylinder":
        return ObstacleSpec(
            name,
            "cylinder",
            x,
            y,
            yaw,
            radius=reader.number("radius", positive=True),
            height=reader.number("height", 1.0, positive=True),
        )
    node = reader.raw("size")
    if node is not None and isinstance(node.value, list) and len(node.value) == 2:
        size = (*reader.numbers("size", 2), reader.number("height", 1.0, positive=True))
    else:
        size = reader.numbers("size", 3)
    if min(size) <= 0:
        reader.fail(reader.raw("size"), f"{reader.what}: size values must be > 0")
    return ObstacleSpec(name, "box", x, y, yaw, size=size, height=size[2])


def parse_world(text: str, source: str = "world.yaml") -> WorldSpec:
    try:
        data, source_map = load_yaml(text, source)  # the limits every fleet input has
    except SpecError as error:
        raise WorldError(f"invalid YAML: {error.message}", error.location) from None
    if data is None:
        raise WorldError("world description is empty", Location(source))
    return world_spec(data, source_map)


def world_spec(data: Any, places: SourceMap) -> WorldSpec:
    """Validate world.yaml's data; `places` says where each value was written (for errors)."""
    source = places.file
    root = _Reader(source, _wrap(data, (), places), "world")
    root.check_keys({"fleet", "physics_rate", "real_time", "clock_rate", "obstacles", "robots"})

    def items(key: str) -> list[_Value]:
        node = root.raw(key)
        if node is None or node.value is None:
            return []
        if not isinstance(node.value, list):
            root.fail(node, f"'{key}' must be a list")
        return node.value

    obstacles = [_obstacle(_Reader(source, item, "obstacle")) for item in items("obstacles")]
    robots = [_robot(_Reader(source, item, "robot")) for item in items("robots")]
    for kind, group, nodes in (("obstacle", obstacles, items("obstacles")), ("robot", robots, items("robots"))):
        seen: set[str] = set()
        for spec, node in zip(group, nodes, strict=False):
            if spec.name in seen:
                root.fail(node, f"duplicate {kind} name '{spec.name}'")
            seen.add(spec.name)
    namespaces: set[str] = set()
    for spec, node in zip(robots, items("robots"), strict=False):
        if spec.namespace in namespaces:
            root.fail(node, f"robot '{spec.name}': namespace '{spec.namespace}' is used twice")
        namespaces.add(spec.namespace)
    fleet = root.string("fleet", "fleet")
    return WorldSpec(
        fleet=fleet,
        physics_rate=root.number("physics_rate", 240.0, positive=True, maximum=10000.0),
        real_time=root.boolean("real_time", True),
        clock_rate=root.number("clock_rate", 100.0, positive=True, maximum=10000.0),
        obstacles=tuple(obstacles),
        robots=tuple(robots),
        source=source,
    )


def load_world(path: str | Path) -> WorldSpec:
    path = Path(path)
    try:
        text = read_input(path, "world description")
    except SpecError as error:
        raise WorldError(error.message, error.location) from None
    return parse_world(text, str(path))
