"""world.yaml -> frozen dataclasses, validated (pure: no pybullet, no ROS).

The dataclasses are the world's own types; pydantic validates world.yaml's data into them (the
constraints are their fields' annotations), reading it through the one reader of positioned YAML
(fleet.spec.yaml_source), so every problem is a WorldError naming the file, line and column of
the offending value and `fleet world` can print one line and exit 2.  A number or a string with
no value (`radius:`) means the same as no key: its default.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

from pydantic import (
    AfterValidator,
    BeforeValidator,
    ConfigDict,
    Discriminator,
    Field,
    Strict,
    StrictBool,
    StrictInt,
    StrictStr,
    Tag,
    TypeAdapter,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from fleet.errors import FleetError, Location, SpecError
from fleet.rules import (
    DEFAULT_ANGULAR_SPEED,
    DEFAULT_BEAMS,
    DEFAULT_CMD_TIMEOUT,
    DEFAULT_LIDAR_RATE,
    DEFAULT_LINEAR_SPEED,
    DEFAULT_MODEL_RADIUS,
    DEFAULT_MODEL_TYPE,
    DEFAULT_ODOM_RATE,
    DEFAULT_PHYSICS_RATE,
    DEFAULT_RANGE_MAX,
    DEFAULT_RANGE_MIN,
    MAX_ANGULAR_SPEED,
    MAX_BEAMS,
    MAX_CMD_TIMEOUT,
    MAX_LIDAR_RANGE,
    MAX_LINEAR_SPEED,
    MAX_MODEL_RADIUS,
    MAX_PHYSICS_RATE,
    MAX_TOPIC_RATE,
    MODEL_TYPES,
    OBSTACLE_TYPES,
    ROS_TOKEN,
)
from fleet.spec.yaml_source import SourceMap, YamlSyntaxError, load_yaml, number_text_hint, read_input

# Footprint rectangles (length along x, width) of the URDF models, measured from their URDFs.
URDF_FOOTPRINTS = {"husky": (0.99, 0.68), "racecar": (0.55, 0.30)}

# -- the world's extent and pace: the rules every world.yaml (and so every spec's world) obeys --------

# Robots and obstacles stand within WORLD_EXTENT of the origin on x and y, and no obstacle is more
# than MAX_OBSTACLE_SIZE long, wide, across or high.  A world 10 km across holds the largest sites a
# fleet simulates (a port, a mine, an airport), so a coordinate or a size beyond it is a typo; far
# beyond it the world stalls.  Measured (one robot, pybullet 3.2.7): pybullet computes in doubles,
# so a robot 10^9 m from the origin drives and stops at a wall as at the origin, and boxes up to
# 10^6 m long hold robots off (at 10^12 m robots drive through them).  What grows with an obstacle
# is the lidar: it cuts a rectangle into pieces 1 m long along its long side (fleet.world.lidar.PIECE),
# each tested by every scan within reach.  With a 10 km wall (10,000 pieces) the world ran at 30x
# real time instead of 49x; with 10^6 m it took 5 s to cut and ran at 2x (25 ms a scan, 4.5 s for
# 100 robots' scans); 10^12 m or 10^300 m are never cut: the world hung after its first step,
# deaf to Ctrl-C.  A square is dearer than a wall of its side, its strips reaching across it: a
# scan beside one 1 km square took 8 ms, beside a 10 km one 28 ms (0.3 ms in an empty world).
WORLD_EXTENT = 5000.0  # m
MAX_OBSTACLE_SIZE = 2 * WORLD_EXTENT  # m: a wall may cross the whole world

# The slowest physics.  Odometry and /clock go out at most once per physics step, so the default
# 50 Hz odometry needs 50 steps a second; URDF models need steps that short to drive straight
# (measured over 5 s at 1 m/s: at 10 Hz the racecar spun round and the husky drifted, at 20-30 Hz
# both ended a few cm off course, at 50 Hz they drove as at 240 Hz); and a real-time world sleeps a
# step at a time, so a robot's cmd_timeout (0.5 s by default) and Ctrl-C are seen within 20 ms
# (at physics_rate 0.001 the world slept 1000 s per step and did not stop on Ctrl-C).
MIN_PHYSICS_RATE = 50.0  # Hz
DEFAULT_CLOCK_RATE = 100.0  # Hz of /clock, or physics_rate when that is lower

# Lidars, contacts, trails and the pick-up of the robots' commands run on slots of whole physics
# steps, about SLOT_RATE a second: a lidar scans at most once per slot.
SLOT_RATE = 60.0  # Hz


def slot_steps(physics_rate: float) -> int:
    """Physics steps per slot."""
    return max(1, round(physics_rate / SLOT_RATE))


def pace_problem(rate: float, what: str, physics_rate: float, per_slot: bool = False) -> str | None:
    """Why the world cannot give `what` (/clock, odometry: once per physics step at most; a lidar,
    per_slot: once per slot at most) `rate` messages a second with `physics_rate` steps a second."""
    steps = slot_steps(physics_rate) if per_slot else 1
    limit = physics_rate / steps
    if rate <= limit:
        return None
    once = f"once every {steps} physics steps" if steps > 1 else "once per physics step"
    return (
        f"{what} {rate:g} Hz is faster than the world publishes it ({once} at physics_rate "
        f"{physics_rate:g}): at most {limit:g} Hz"
    )


class WorldError(FleetError):
    """world.yaml is unreadable or invalid."""


# -- field types: what each value of world.yaml may be ---------------------------------------------
# A failed check of ours raises a PydanticCustomError whose type tells _world_error how to word it:
# "field": "<what>: '<key>' <message>"; "value": "<what>: <message>"; "check", a rule across
# values (context `at`: the path, below the checked value, that it points at): "<what>: <message>",
# or the message alone for the world's own rules.


def _field_problem(message: str) -> PydanticCustomError:
    return PydanticCustomError("field", message)


def _value_problem(message: str) -> PydanticCustomError:
    return PydanticCustomError("value", message)


def _check_problem(message: str, at: tuple = ()) -> PydanticCustomError:
    return PydanticCustomError("check", message, {"at": at})


def _valid_name(value: str) -> str:
    if not ROS_TOKEN.fullmatch(value):
        raise _value_problem(
            f"'{value}' is not a valid name (letters, digits and underscores, not starting with a digit)"
        )
    return value


def _one_of(kinds: tuple[str, ...], what: str) -> AfterValidator:
    def check(value: str) -> str:
        if value not in kinds:
            raise _value_problem(f"unknown {what} '{value}' (known: {', '.join(kinds)})")
        return value

    return AfterValidator(check)


def _within(low: int, high: int) -> AfterValidator:
    def check(value: int) -> int:
        if not low <= value <= high:
            raise _field_problem(f"must be in {low}..{high}, got {value}")
        return value

    return AfterValidator(check)


def _list_of(*counts: int) -> BeforeValidator:
    def check(value: Any) -> Any:
        if not isinstance(value, list) or len(value) not in counts:
            raise _field_problem(f"must be a list of {counts[-1]} numbers")
        return value

    return BeforeValidator(check)


def _in_world(value: float) -> float:
    if abs(value) > WORLD_EXTENT:
        raise _field_problem(f"must be in {-WORLD_EXTENT:g}..{WORLD_EXTENT:g} m (the world's extent), got {value:g}")
    return value


def _at_most(limit: float) -> AfterValidator:
    def check(value: float) -> float:
        if value > limit:
            raise _field_problem(
                f"must be at most {limit:g} m (the world is {2 * WORLD_EXTENT:g} m across), got {value:g}"
            )
        return value

    return AfterValidator(check)


Number = Annotated[float, Strict(), Field(allow_inf_nan=False)]  # an int or a float, not a bool
Name = Annotated[StrictStr, AfterValidator(_valid_name)]
ObstacleType = Annotated[StrictStr, _one_of(OBSTACLE_TYPES, "type")]
Coordinate = Annotated[Number, AfterValidator(_in_world)]  # x or y of a place in the world, m
Point = Annotated[tuple[Coordinate, Coordinate], _list_of(2)]
Dimension = Annotated[Number, _at_most(MAX_OBSTACLE_SIZE)]  # an obstacle's length, width or height, m


class _FromYaml:
    """What the types read from world.yaml share: unknown keys are errors, and a number or a
    string written with no value (`radius:`) is as if not written (its default, or missing)."""

    __pydantic_config__ = ConfigDict(extra="forbid")

    @model_validator(mode="before")
    @classmethod
    def _null_means_default(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        defaulted = _number_or_string_fields(cls)  # type: ignore[arg-type]  # classes hash by identity
        return {key: value for key, value in data.items() if value is not None or key not in defaulted}


@functools.cache
def _number_or_string_fields(kind: type) -> frozenset[str]:
    hints = typing.get_type_hints(kind, include_extras=True)
    return frozenset(
        name for name, hint in hints.items() if typing.get_origin(hint) is Annotated and hint.__origin__ in (float, str)
    )


# -- the world's types -----------------------------------------------------------------------------


@dataclass(frozen=True)
class Pose2D(_FromYaml):
    x: Coordinate = 0.0
    y: Coordinate = 0.0
    yaw: Number = 0.0


@dataclass(frozen=True)
class ModelSpec(_FromYaml):
    type: Annotated[StrictStr, _one_of(MODEL_TYPES, "model type")] = DEFAULT_MODEL_TYPE
    radius: Annotated[Number, Field(gt=0, le=MAX_MODEL_RADIUS)] = DEFAULT_MODEL_RADIUS  # light: footprint circle
    length: Annotated[Number, Field(gt=0, le=10.0)] = 0.99  # URDF models: footprint rectangle (along x)
    width: Annotated[Number, Field(gt=0, le=10.0)] = 0.68
    max_linear_speed: Annotated[Number, Field(gt=0.0, le=MAX_LINEAR_SPEED)] = DEFAULT_LINEAR_SPEED
    max_angular_speed: Annotated[Number, Field(gt=0.0, le=MAX_ANGULAR_SPEED)] = DEFAULT_ANGULAR_SPEED

    @model_validator(mode="before")
    @classmethod
    def _footprint_of_type(cls, data: Any) -> Any:
        """In world.yaml a URDF model's length and width default to its URDF's footprint."""
        if isinstance(data, dict) and isinstance(data.get("type"), str) and data["type"] in URDF_FOOTPRINTS:
            footprint = dict(zip(("length", "width"), URDF_FOOTPRINTS[data["type"]], strict=True))
            data = {**data, **{key: value for key, value in footprint.items() if data.get(key) is None}}
        return data

    @property
    def is_round(self) -> bool:
        return self.type == "light"

    @property
    def bounding_radius(self) -> float:
        if self.is_round:
            return self.radius
        return math.hypot(self.length, self.width) / 2.0


@dataclass(frozen=True)
class LidarSpec(_FromYaml):
    beams: Annotated[StrictInt, _within(1, MAX_BEAMS)] = DEFAULT_BEAMS
    rate: Annotated[Number, Field(gt=0, le=MAX_TOPIC_RATE)] = DEFAULT_LIDAR_RATE
    range_min: Annotated[Number, Field(ge=0.0)] = DEFAULT_RANGE_MIN
    range_max: Annotated[Number, Field(gt=0, le=MAX_LIDAR_RANGE)] = DEFAULT_RANGE_MAX
    angle_min: Annotated[Number, Field(ge=-2 * math.pi)] = -math.pi
    # angle_max is exclusive for a full circle (the last beam is angle_max - step).
    angle_max: Annotated[Number, Field(le=2 * math.pi)] = math.pi

    @model_validator(mode="after")
    def _consistent(self) -> LidarSpec:
        if self.range_min >= self.range_max:
            raise _check_problem("range_min must be below range_max", ("range_min",))
        if self.angle_min >= self.angle_max or self.angle_max - self.angle_min > 2 * math.pi + 1e-9:
            raise _check_problem("need angle_min < angle_max spanning at most 2*pi", ("angle_min",))
        return self

    @property
    def full_circle(self) -> bool:
        return abs((self.angle_max - self.angle_min) - 2 * math.pi) < 1e-6

    @property
    def increment(self) -> float:
        span = self.angle_max - self.angle_min
        # A full circle must not repeat its first beam; a partial fan includes both ends.
        return span / self.beams if self.full_circle else span / max(self.beams - 1, 1)


def _namespace(value: str) -> str:
    namespace = value if value.startswith("/") else "/" + value
    namespace = namespace.rstrip("/") or "/"
    if namespace != "/" and not all(ROS_TOKEN.fullmatch(part) for part in namespace[1:].split("/")):
        raise _value_problem(f"'{namespace}' is not a valid ROS namespace")
    return namespace


@dataclass(frozen=True)
class RobotSpec(_FromYaml):
    name: Name
    namespace: Annotated[StrictStr, AfterValidator(_namespace)]  # world.yaml: /<name> unless given
    model: ModelSpec = field(default_factory=ModelSpec)
    pose: Pose2D = field(default_factory=Pose2D)
    lidar: LidarSpec = field(default_factory=LidarSpec)
    odom_rate: Annotated[Number, Field(gt=0, le=MAX_TOPIC_RATE)] = DEFAULT_ODOM_RATE
    cmd_timeout: Annotated[Number, Field(gt=0, le=MAX_CMD_TIMEOUT)] = DEFAULT_CMD_TIMEOUT
    ground_truth: StrictBool = False

    def reload_change(self, new: RobotSpec) -> str | None:
        """What the world does when a reload turns this robot into `new`: "respawn" it at its new
        spawn pose (its odom starts there, as after a restart), "rebuild" it where it stands
        (another model, lidar or rate), or nothing."""
        if new.pose != self.pose:
            return "respawn"
        return "rebuild" if new != self else None

    @model_validator(mode="before")
    @classmethod
    def _namespace_of_name(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("namespace") is None and isinstance(data.get("name"), str):
            data = {**data, "namespace": f"/{data['name']}"}
        return data


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
    fleet: str
    physics_rate: float
    real_time: bool
    clock_rate: float
    obstacles: tuple[ObstacleSpec, ...]
    robots: tuple[RobotSpec, ...]
    source: str | None = None


def default_clock_rate(physics_rate: float) -> float:
    """/clock's rate when none is given: DEFAULT_CLOCK_RATE, or every step of a slower physics."""
    return min(DEFAULT_CLOCK_RATE, physics_rate)


def _fast_enough(physics_rate: float) -> float:
    if physics_rate < MIN_PHYSICS_RATE:
        raise _field_problem(
            f"must be at least {MIN_PHYSICS_RATE:g} steps a second (one per message of the default "
            f"{DEFAULT_ODOM_RATE:g} Hz odometry; slower steps drive URDF models off course), got {physics_rate:g}"
        )
    return physics_rate


# -- world.yaml's forms of an obstacle and of the world ----------------------------------------------


@dataclass(frozen=True, kw_only=True)
class _Box(_FromYaml):
    """A box (or wall) as world.yaml writes it: `size` is [x, y, z], or [x, y] and `height`."""

    name: Name
    type: ObstacleType
    position: Point
    yaw: Number = 0.0
    size: Annotated[tuple[Dimension, ...], _list_of(2, 3)]
    height: Annotated[Dimension, Field(gt=0)] = 1.0
    radius: Any = None  # a cylinder's, ignored

    @model_validator(mode="before")
    @classmethod
    def _height_in_size(cls, data: Any) -> Any:
        """With three sizes the third is the height, and a `height` key is ignored."""
        if isinstance(data, dict) and isinstance(data.get("size"), list) and len(data["size"]) == 3:
            return {key: value for key, value in data.items() if key != "height"}
        return data

    @model_validator(mode="after")
    def _positive(self) -> _Box:
        if min(self.size) <= 0:
            raise _check_problem("size values must be > 0", ("size",))
        return self

    def spec(self) -> ObstacleSpec:
        length, width, *rest = self.size  # 2 or 3 values (validated)
        height = rest[0] if rest else self.height
        return ObstacleSpec(self.name, "box", *self.position, self.yaw, size=(length, width, height), height=height)


@dataclass(frozen=True, kw_only=True)
class _Cylinder(_FromYaml):
    name: Name
    type: ObstacleType
    position: Point
    yaw: Number = 0.0
    radius: Annotated[Number, Field(gt=0), _at_most(MAX_OBSTACLE_SIZE / 2)]
    height: Annotated[Dimension, Field(gt=0)] = 1.0
    size: Any = None  # a box's, ignored

    def spec(self) -> ObstacleSpec:
        return ObstacleSpec(self.name, "cylinder", *self.position, self.yaw, radius=self.radius, height=self.height)


def _shape(data: Any) -> str:
    return "cylinder" if isinstance(data, dict) and data.get("type") == "cylinder" else "box"


_Obstacle = Annotated[Annotated[_Box, Tag("box")] | Annotated[_Cylinder, Tag("cylinder")], Discriminator(_shape)]


@dataclass(frozen=True)
class _WorldFile(_FromYaml):
    obstacles: tuple[_Obstacle, ...] = ()
    robots: tuple[RobotSpec, ...] = ()
    fleet: StrictStr = "fleet"
    physics_rate: Annotated[Number, Field(le=MAX_PHYSICS_RATE), AfterValidator(_fast_enough)] = DEFAULT_PHYSICS_RATE
    real_time: StrictBool = True
    clock_rate: Annotated[Number, Field(gt=0, le=MAX_TOPIC_RATE)] | None = None  # default: default_clock_rate

    @model_validator(mode="before")
    @classmethod
    def _no_items_if_null(cls, data: Any) -> Any:
        if isinstance(data, dict):
            return {
                key: value for key, value in data.items() if key not in ("obstacles", "robots") or value is not None
            }
        return data

    @field_validator("obstacles", "robots")
    @classmethod
    def _unique_names(cls, items: tuple, info: ValidationInfo) -> tuple:
        kind = (info.field_name or "items")[:-1]
        seen: set[str] = set()
        for index, item in enumerate(items):
            if item.name in seen:
                raise _check_problem(f"duplicate {kind} name '{item.name}'", (index,))
            seen.add(item.name)
        return items

    @field_validator("robots")
    @classmethod
    def _unique_namespaces(cls, robots: tuple[RobotSpec, ...]) -> tuple[RobotSpec, ...]:
        namespaces: set[str] = set()
        for index, robot in enumerate(robots):
            if robot.namespace in namespaces:
                raise _check_problem(f"robot '{robot.name}': namespace '{robot.namespace}' is used twice", (index,))
            namespaces.add(robot.namespace)
        return robots

    @model_validator(mode="after")
    def _paced(self) -> _WorldFile:
        """What is published per physics step or per slot is not asked for faster than that."""
        physics = self.physics_rate
        if self.clock_rate is not None and (problem := pace_problem(self.clock_rate, "clock_rate", physics)):
            raise _check_problem(problem, ("clock_rate",))
        for index, robot in enumerate(self.robots):
            if problem := pace_problem(robot.odom_rate, "odom_rate", physics):
                raise _check_problem(f"robot '{robot.name}': {problem}", ("robots", index, "odom_rate"))
            if problem := pace_problem(robot.lidar.rate, "lidar rate", physics, per_slot=True):
                raise _check_problem(f"robot '{robot.name}': {problem}", ("robots", index, "lidar", "rate"))
        return self

    def spec(self, source: str) -> WorldSpec:
        return WorldSpec(
            fleet=self.fleet,
            physics_rate=self.physics_rate,
            real_time=self.real_time,
            clock_rate=self.clock_rate if self.clock_rate is not None else default_clock_rate(self.physics_rate),
            obstacles=tuple(entry.spec() for entry in self.obstacles),
            robots=self.robots,
            source=source,
        )


# -- reading world.yaml ----------------------------------------------------------------------------


def parse_world(text: str, source: str = "world.yaml") -> WorldSpec:
    try:
        data, positions = load_yaml(text, source)
    except YamlSyntaxError as error:
        raise WorldError(f"invalid YAML: {error.problem}", error.location) from None
    except SpecError as error:  # duplicate keys and the like
        raise WorldError(error.message, error.location) from None
    if data is None:
        raise WorldError("world description is empty", Location(source))
    return world_spec(data, positions)


def world_spec(data: Any, places: SourceMap) -> WorldSpec:
    """Validate world.yaml's data; `places` says where each value was written (for errors)."""
    try:
        world = _world_file().validate_python(data)
    except ValidationError as error:
        raise _world_error(error, data, places) from None
    return world.spec(places.file)


def load_world(path: str | Path) -> WorldSpec:
    path = Path(path)
    try:
        text = read_input(path, "world description")
    except SpecError as error:
        raise WorldError(error.message, error.location) from None
    return parse_world(text, str(path))


@functools.cache
def _world_file() -> TypeAdapter:
    return TypeAdapter(_WorldFile)


# -- pydantic's errors in world.yaml's words ---------------------------------------------------------

_UNKNOWN = ("extra_forbidden", "unexpected_keyword_argument", "invalid_key")  # the last: `1: x`
_NOT_A_MAPPING = ("dataclass_type", "dataclass_args_type", "model_attributes_type", "dict_type")
_NOT_A_NUMBER = ("float_type", "float_parsing", "finite_number")
_WORDING = {
    "float_type": "must be a number, got {input!r}",
    "float_parsing": "must be a number, got {input!r}",
    "finite_number": "must be a number, got {input!r}",
    "greater_than": "must be > {gt:g}, got {input}",
    "greater_than_equal": "must be >= {ge}, got {input}",
    "less_than_equal": "must be <= {le}, got {input}",
    "int_type": "must be an integer, got {input!r}",
    "bool_type": "must be true or false, got {input!r}",
    "string_type": "must be a string, got {input!r}",
}


def _world_error(error: ValidationError, data: Any, positions: SourceMap) -> WorldError:
    """The problem the hand-written order would meet first, as one located line."""
    problems: list[dict[str, Any]] = [{**problem, "loc": _plain(problem["loc"])} for problem in error.errors()]
    first = problems[0]
    # Unknown keys of a mapping are reported before its values' problems.
    unknown = [p for p in problems if p["type"] in _UNKNOWN and first["loc"][: len(p["loc"]) - 1] == p["loc"][:-1]]
    problem = min(unknown, key=lambda p: len(p["loc"])) if unknown else first
    loc, kind, message = problem["loc"], problem["type"], problem["msg"]
    context = {**problem.get("ctx", {}), "input": problem["input"]}
    parent, key = loc[:-1], loc[-1] if loc else None
    at = loc
    if kind in _UNKNOWN:
        allowed = ", ".join(sorted(_keys_at(parent)))
        # An item's keys are checked before its name: an unknown one names the kind only.
        text = f"unknown key '{key}' in {_what(data, parent, named=len(parent) != 2)} (allowed: {allowed})"
    elif kind == "missing":
        text, at = f"{_what(data, parent)}: missing '{key}'", parent
    elif kind in _NOT_A_MAPPING:
        text = f"{_what(data, loc)} must be a mapping"
    elif kind == "tuple_type" and len(loc) == 1:
        text = f"'{key}' must be a list"
    elif kind == "check":
        at, what = (*loc, *problem["ctx"]["at"]), _what(data, loc)
        text = message if what == "world" else f"{what}: {message}"
    elif kind == "value":
        text = f"{_what(data, parent)}: {message}"
    elif isinstance(key, int):  # an item of a list of numbers
        wording = message if kind == "field" else f"must contain numbers, got {problem['input']!r}"
        text = f"{_what(data, loc[:-2])}: '{loc[-2]}' {wording}"
    else:
        wording = message if kind == "field" else _WORDING.get(kind, message).format(**context)
        text = f"{_what(data, parent)}: '{key}' {wording}"
    if kind in _NOT_A_NUMBER and (hint := number_text_hint(problem["input"])):
        text += f" ({hint})"
    return WorldError(text, positions.locate(at))


def _plain(loc: tuple) -> tuple:
    """pydantic's location without the obstacle shape it chose (`obstacles.0.box.size`)."""
    return tuple(part for index, part in enumerate(loc) if not (index == 2 and loc[0] == "obstacles"))


def _what(data: Any, loc: tuple, named: bool = True) -> str:
    """How messages name the mapping at `loc`: world, robot 'r1', robot 'r1'.pose, obstacle."""
    if len(loc) < 2:
        return "world"
    kind = "obstacle" if loc[0] == "obstacles" else "robot"
    item = data[loc[0]][loc[1]]
    name = item.get("name") if isinstance(item, dict) else None
    what = f"{kind} '{name}'" if named and isinstance(name, str) and ROS_TOKEN.fullmatch(name) else kind
    return ".".join([what, *map(str, loc[2:])])


def _keys_at(loc: tuple) -> list[str]:
    """The keys world.yaml allows in the mapping at `loc`."""
    kind: Any = _WorldFile
    for part in loc:
        if isinstance(part, str):
            kind = _dataclass_in(typing.get_type_hints(kind, include_extras=True)[part])
    return [item.name for item in dataclasses.fields(kind)]


def _dataclass_in(hint: Any) -> Any:
    """The first dataclass inside a type hint (through Annotated, tuple and union)."""
    if dataclasses.is_dataclass(hint):
        return hint
    for argument in typing.get_args(hint):
        found = _dataclass_in(argument)
        if found is not None:
            return found
    return None
