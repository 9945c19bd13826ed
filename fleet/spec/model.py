"""The fleet spec schema (pydantic).  Field documentation here is the reference for docs/spec.md."""

from __future__ import annotations

from typing import Annotated, Any, ClassVar, Literal

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, PrivateAttr, model_validator

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
    LOCAL_AGENT,
    MAX_ANGULAR_SPEED,
    MAX_BEAMS,
    MAX_CMD_TIMEOUT,
    MAX_DOMAIN_ID,
    MAX_LIDAR_RANGE,
    MAX_LINEAR_SPEED,
    MAX_MODEL_RADIUS,
    MAX_PHYSICS_RATE,
    MAX_TOPIC_RATE,
    ModelType,
    ObstacleKind,
)
from fleet.spec.yaml_source import SourceMap


def _ints_to_floats(data: Any, keep: frozenset[str] = frozenset()) -> Any:
    """Ints (not bools) as floats, and YAML lists as the tuples the models declare (position,
    size): strict mode takes `x: 1` for a float, but refuses a list where a tuple is declared."""
    if not isinstance(data, dict):
        return data
    out = {}
    for key, value in data.items():
        if key in keep:
            out[key] = value
        elif isinstance(value, int) and not isinstance(value, bool):
            out[key] = float(value)
        elif isinstance(value, list) and key in ("position", "size"):
            out[key] = tuple(float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value)
        else:
            out[key] = value
    return out


def _one_value(value: Any) -> Any:
    """A launch argument is one scalar; said so, not as the first member of the union that failed."""
    if value is None or isinstance(value, (list, dict)):
        kind = "null" if value is None else "a list" if isinstance(value, list) else "a mapping"
        raise ValueError(f"a launch argument takes one value (text, a number, true or false), not {kind}")
    return value


ScalarArg = Annotated[bool | int | float | str, BeforeValidator(_one_value)]

# process: one process per node; robot: a robot's fleet_nodes share one process; agent: the
# fleet_nodes of all robots of an agent share host processes of up to group_size robots each.
DEFAULT_GROUP_SIZE = 25  # robots per host process under isolation: agent (bench/results/isolation.md)
DEFAULT_MAX_ROBOTS = 300  # robots one agent accepts (the 2-core measurement of bench/README.md)


class Strict(BaseModel):
    # Unknown keys are errors (with a did-you-mean, see load.py); no silent coercion of
    # strings into numbers.
    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


class Measured(Strict):
    """A model of measurements: `x: 1` is read as 1.0 and `position: [1, 2]` as (1.0, 2.0) (strict
    mode alone would refuse the list)."""

    integer_fields: ClassVar[frozenset[str]] = frozenset()

    @model_validator(mode="before")
    @classmethod
    def _ints_are_floats(cls, data: Any) -> Any:
        return _ints_to_floats(data, keep=cls.integer_fields)


class Pose(Measured):
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0  # radians


class Lidar(Measured):
    beams: int = Field(DEFAULT_BEAMS, ge=1, le=MAX_BEAMS)
    rate: float = Field(DEFAULT_LIDAR_RATE, gt=0, le=MAX_TOPIC_RATE)
    range_min: float = Field(DEFAULT_RANGE_MIN, ge=0)
    range_max: float = Field(DEFAULT_RANGE_MAX, gt=0, le=MAX_LIDAR_RANGE)

    integer_fields: ClassVar[frozenset[str]] = frozenset({"beams"})


class Model(Measured):
    """The simulated body: `light` (planar one-body diff drive, cheap) or a URDF from pybullet_data."""

    type: ModelType = DEFAULT_MODEL_TYPE
    radius: float = Field(DEFAULT_MODEL_RADIUS, gt=0, le=MAX_MODEL_RADIUS)  # footprint radius of the light model, m
    max_linear_speed: float = Field(DEFAULT_LINEAR_SPEED, gt=0, le=MAX_LINEAR_SPEED)  # m/s
    max_angular_speed: float = Field(DEFAULT_ANGULAR_SPEED, gt=0, le=MAX_ANGULAR_SPEED)  # rad/s


class ModelOverride(Measured):
    """A robot's changes to the default model: only the fields it sets."""

    type: ModelType | None = None
    radius: float | None = Field(None, gt=0, le=MAX_MODEL_RADIUS)
    max_linear_speed: float | None = Field(None, gt=0, le=MAX_LINEAR_SPEED)
    max_angular_speed: float | None = Field(None, gt=0, le=MAX_ANGULAR_SPEED)


class Obstacle(Measured):
    name: str
    type: ObstacleKind
    position: tuple[float, float]  # x, y of the centre, m
    yaw: float = 0.0
    size: tuple[float, float, float] | None = None  # box/wall: x, y, z extent, m
    radius: float | None = Field(None, gt=0)  # cylinder
    height: float = Field(1.0, gt=0)  # cylinder

    @model_validator(mode="after")
    def _shape_complete(self) -> Obstacle:
        if self.type in ("box", "wall"):
            if self.size is None:
                raise ValueError(f"a {self.type} needs size: [x, y, z]")
            if min(self.size) <= 0:
                raise ValueError("size must be positive in every axis")
            if self.radius is not None:
                raise ValueError(f"a {self.type} has a size, not a radius")
        if self.type == "cylinder":
            if self.radius is None:
                raise ValueError("a cylinder needs radius")
            if self.size is not None:
                raise ValueError("a cylinder has radius and height, not size")
        return self


class World(Measured):
    agent: str | None = None  # defaults to defaults.agent
    physics_rate: float = Field(DEFAULT_PHYSICS_RATE, gt=0, le=MAX_PHYSICS_RATE)  # Hz
    real_time: bool = True
    # Hz of /clock, at most physics_rate; None: fleet.world.description.default_clock_rate
    clock_rate: float | None = Field(None, gt=0, le=MAX_TOPIC_RATE)
    odom_rate: float = Field(DEFAULT_ODOM_RATE, gt=0, le=MAX_TOPIC_RATE)
    cmd_timeout: float = Field(DEFAULT_CMD_TIMEOUT, gt=0, le=MAX_CMD_TIMEOUT)
    obstacles: list[Obstacle] = []


class Ros(Strict):
    domain_id: int = Field(0, ge=0, le=MAX_DOMAIN_ID)
    use_sim_time: bool = True
    # How ROS traffic crosses computers (docs/multi-computer.md): `dds`, nodes talking DDS
    # directly, found through the fleet's discovery server; `zenoh`, DDS kept on each computer
    # and the topics that cross carried by the agents' bridges over the fleet's Zenoh network.
    transport: Literal["dds", "zenoh"] = "dds"


class Agent(Strict):
    description: str = ""
    max_robots: int = Field(DEFAULT_MAX_ROBOTS, ge=1)  # robots this agent accepts, any isolation


Isolation = Literal["process", "robot", "agent"]


class Defaults(Strict):
    template: str = "diff_drive"
    agent: str = LOCAL_AGENT
    isolation: Isolation = "agent"
    group_size: int = Field(DEFAULT_GROUP_SIZE, ge=1)  # robots per host process (isolation: agent)
    model: Model = Model()
    lidar: Lidar = Lidar()
    parameters: dict[str, dict[str, Any]] = {}  # node -> parameter -> value
    launch_args: dict[str, ScalarArg] = {}


class Robot(Strict):
    name: str
    namespace: str | None = None  # default: /<name>
    agent: str | None = None
    template: str | None = None
    isolation: Isolation | None = None
    simulated: bool = True  # hosted by the shared world (false for a real robot)
    model: ModelOverride = ModelOverride()
    lidar: Lidar | None = None
    pose: Pose = Pose()
    parameters: dict[str, dict[str, Any]] = {}
    launch_args: dict[str, ScalarArg] = {}


class FleetSpec(Strict):
    fleet: str
    description: str = ""
    templates: str | None = None  # directory of the robot's templates, relative to the spec file
    ros: Ros = Ros()
    world: World | None = None
    agents: dict[str, Agent] = {LOCAL_AGENT: Agent()}
    defaults: Defaults = Defaults()
    robots: list[Robot] = Field(min_length=1)

    # Filled by the loader: where the spec came from (not part of the YAML, so not a field: a
    # field, even one left out of dumps, would be a key a spec could set).
    _source_file: str = PrivateAttr("<spec>")
    _source_map: SourceMap | None = PrivateAttr(None)  # positions in the spec file

    @property
    def source_file(self) -> str:
        return self._source_file

    def where(self, *path: Any) -> str:
        """`file:line:col` of a place in the spec, for messages and --explain."""
        if self._source_map is None:
            return self.source_file
        return str(self._source_map.locate(tuple(path)))

    def robot(self, name: str) -> Robot | None:
        return next((robot for robot in self.robots if robot.name == name), None)
