"""The control-plane protocol: Zenoh key space and versioned JSON messages.

Every message is a JSON object with `v` (protocol version) and `kind`.  Messages are validated
with pydantic on receipt; anything malformed, truncated, oversized, of another version or naming
files outside a bundle directory raises ProtocolError, which the receiver turns into an error
reply.  docs/control-plane.md is the reference for people; keep the two in step.

Key space (every key lives under the fleet's name, so several fleets share one router):

    fleet/<fleet>/agent/<agent>/apply      queryable  ApplyRequest -> ApplyReply
    fleet/<fleet>/agent/<agent>/logs       queryable  LogsRequest  -> LogsReply
    fleet/<fleet>/agent/<agent>/param      queryable  ParamRequest -> ParamReply
    fleet/<fleet>/agent/<agent>/restart    queryable  RestartRequest -> RestartReply
    fleet/<fleet>/agent/<agent>/world      queryable  WorldRequest -> WorldReply (the agent running the world)
    fleet/<fleet>/status/agent/<agent>     queryable  (no payload) -> StatusReply
    fleet/<fleet>/status/registry          queryable  (router)     -> RegistryReply
    fleet/<fleet>/plan                     put        PlanRecord (deploy -> router registry)
    fleet/<fleet>/desired/<agent>          put        ApplyRequest (deploy/down -> router registry)
                                           queryable  (router) DesiredQuery -> the stored ApplyRequests
    fleet/<fleet>/alive/agent/<agent>      liveliness token, one per fleet the agent serves
    fleet/<fleet>/data/-to/<agent>         put        a batch of CDR-serialized ROS messages for that
                                                      agent's bridge (`zenoh` transport, fleet.dataplane.batch)
    fleet/<fleet>/data/-imports/<agent>/<ros topic>
                                           liveliness token: that agent's bridge brings in that topic

An agent declares its queryables with `*` in the fleet chunk: it serves whatever fleet is
deployed to it, and learns that it serves a fleet from the first apply it accepts.
"""

from __future__ import annotations

import hashlib
import ipaddress
import json
from collections.abc import Mapping
from typing import Annotated, Any, Final, Literal, TypeVar

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from fleet.errors import validation_message
from fleet.rules import MAX_DOMAIN_ID, ROS_TOKEN_PATTERN, SIMULATED_OPTION, ros_name_problem
from fleet.rules import key_name_problem as key_name_problem
from fleet.wire.digests import cold_json, digest_of, hot_digest
from fleet.wire.limits import MAX_BUNDLES as MAX_BUNDLES
from fleet.wire.limits import MAX_FILE_BYTES as MAX_FILE_BYTES
from fleet.wire.limits import MAX_FILES_PER_BUNDLE as MAX_FILES_PER_BUNDLE
from fleet.wire.limits import MAX_LOG_LINES as MAX_LOG_LINES
from fleet.wire.limits import MAX_MESSAGE_BYTES as MAX_MESSAGE_BYTES
from fleet.wire.limits import check_file_name as check_file_name
from fleet.wire.limits import files_problem

VERSION: Final = 1


def address_problem(address: object) -> str | None:
    """None when `address` is an IPv4 address (what an agent reports and DDS listens on)."""
    try:
        ipaddress.IPv4Address(address)
    except (ipaddress.AddressValueError, ValueError, TypeError):
        return f"{address!r} is not an IPv4 address (such as 10.0.0.5)"
    return None


def address_port_problem(value: str) -> str | None:
    address, _, port = value.rpartition(":")
    if not port.isdigit() or not 0 < int(port) < 65536:
        return f"{value!r} is not address:port (such as 10.0.0.5:11811)"
    return address_problem(address)


class ProtocolError(ValueError):
    """A message that cannot be accepted; `code` is machine-readable, str() is for people."""

    def __init__(self, message: str, code: str = "invalid"):
        super().__init__(message)
        self.code = code


# The codes of refusals of what a request names or holds (a robot or node the agent does not run,
# a name it cannot take): the asker's input is wrong, not the fleet.  The client's error for them
# is a BadRequest (exit 2); every other code is a failure of the request (exit 1).
INPUT_ERRORS = frozenset({"invalid", "not_found"})
REFUSED = "refused"  # ParamReply.code of a value the node refused: the asker's input, said with the value


# ---------------------------------------------------------------------------------------------
# Keys


def apply_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/agent/{agent}/apply"


def logs_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/agent/{agent}/logs"


def param_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/agent/{agent}/param"


def restart_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/agent/{agent}/restart"


def world_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/agent/{agent}/world"


def echo_keys(fleet: str, agent: str) -> tuple[str, str]:
    """(ping, pong): the router puts every ping it receives back on the pong key, so a bridge
    learns whether its publications and subscriptions really pass through the router."""
    return f"fleet/{fleet}/agent/{agent}/echo/ping", f"fleet/{fleet}/agent/{agent}/echo/pong"


def agent_status_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/status/agent/{agent}"


def registry_key(fleet: str) -> str:
    return f"fleet/{fleet}/status/registry"


def status_query(fleet: str | None = None) -> str:
    """One wildcard get on this key reaches every agent (and the router's registry)."""
    return f"fleet/{fleet or '*'}/status/**"


# A fleet name no fleet has (names never start with "."): the router answers a registry query for
# any fleet name, so asking this one tells whether the router answers this client at all.
NO_FLEET = ".none"


def plan_key(fleet: str) -> str:
    return f"fleet/{fleet}/plan"


def desired_key(fleet: str, agent: str) -> str:
    """The router keeps the latest apply of each agent here, for agents that were away."""
    return f"fleet/{fleet}/desired/{agent}"


def alive_key(fleet: str, agent: str) -> str:
    return f"fleet/{fleet}/alive/agent/{agent}"


def data_key(fleet: str, topic: str) -> str:
    """A ROS topic's place under the fleet's data keys ("/robot1/odom" -> fleet/f/data/robot1/odom)."""
    return f"fleet/{fleet}/data/{topic.strip('/')}"


# Chunks that no ROS topic's key can have (a ROS name token never holds "-"): the `zenoh`
# transport's own keys under fleet/<fleet>/data, which the agents' access rules already cover.
BATCH_CHUNK, IMPORTS_CHUNK = "-to", "-imports"


def batch_key(fleet: str, agent: str) -> str:
    """Where bridges put the batches of ROS messages that `agent`'s bridge brings in."""
    return data_key(fleet, f"{BATCH_CHUNK}/{agent}")


def import_token_key(fleet: str, agent: str, topic: str) -> str:
    """The liveliness token by which `agent`'s bridge says it brings in `topic`."""
    return data_key(fleet, f"{IMPORTS_CHUNK}/{agent}/{topic.strip('/')}")


def imported_topic(fleet: str, token_key: str) -> tuple[str, str] | None:
    """(agent, topic) of an import token's key, None for any other key."""
    prefix = data_key(fleet, IMPORTS_CHUNK) + "/"
    agent, _, topic = str(token_key).removeprefix(prefix).partition("/")
    if not str(token_key).startswith(prefix) or not agent or not topic:
        return None
    return agent, f"/{topic}"


def agent_key_exprs(agent: str) -> list[str]:
    """Every key an agent answers, announces or asks on, in any fleet: what the router's access
    rules let an agent's certificate reach (fleet/*/data/** is the fleets' shared ROS data)."""
    return [
        f"fleet/*/agent/{agent}/**",
        agent_status_key("*", agent),
        alive_key("*", agent),
        desired_key("*", agent),
        data_key("*", "**"),
    ]


def agent_asks_key_exprs() -> list[str]:
    """Keys any agent may query besides its own: every agent's status, where an agent learns the
    address of its fleet's discovery host (fleet.server.agent, _find_discovery_hosts)."""
    return [agent_status_key("*", "*")]


def fleet_of_key(key: str) -> str | None:
    """The fleet chunk of a `fleet/<fleet>/...` key, or None when it is a wildcard."""
    parts = str(key).split("/")
    if len(parts) < 2 or parts[0] != "fleet" or "*" in parts[1] or "$" in parts[1]:
        return None
    return parts[1]


# ---------------------------------------------------------------------------------------------
# Field checks


def _check_key_name(value: str) -> str:
    problem = key_name_problem(value)
    if problem:
        raise ValueError(problem)
    return value


def _check_ros_name(value: str) -> str:
    if ros_name_problem(value) is not None:
        raise ValueError(f"{value!r} is not a valid ROS name")
    return value


class Message(BaseModel):
    model_config = ConfigDict(extra="forbid")

    v: Literal[1] = VERSION


ParamValue = bool | int | float | str | list[bool] | list[int] | list[float] | list[str]

# A deploy's generation is its time.time_ns() (fleet.plan.desired): an int64 until the year 2262.
# An agent refuses any generation below the one it holds, so a larger one, once accepted, would
# hold its fleet against every later deploy.
MAX_GENERATION: Final = 2**63 - 1
Generation = Annotated[int, Field(ge=0, le=MAX_GENERATION)]


# ---------------------------------------------------------------------------------------------
# Apply: a fleet's complete desired state for one agent


def simulated_option(options: Mapping[str, Any]) -> bool:
    """Whether a bundle's options leave its robot simulated (all but a real robot's do)."""
    return options.get(SIMULATED_OPTION) is not False


class BundleMessage(BaseModel):
    """fleet.expand.Bundle on the wire (see docs/architecture.md, Bundles)."""

    model_config = ConfigDict(extra="forbid")

    name: str
    kind: Literal["robot", "world"]
    entry: str
    files: dict[str, str]
    options: dict[str, str | int | float | bool] = {}
    hot_files: list[str] = []
    digest: str = Field(pattern=r"^[0-9a-f]{16,128}$")

    @field_validator("name")
    @classmethod
    def _name_is_ros_name(cls, value: str) -> str:
        return _check_ros_name(value)

    @field_validator("entry")
    @classmethod
    def _entry_plain(cls, value: str) -> str:
        return check_file_name(value)

    @field_validator("files")
    @classmethod
    def _files_plain_and_small(cls, files: dict[str, str]) -> dict[str, str]:
        if problem := files_problem(files):
            raise ValueError(problem)
        return files

    @field_validator("options")
    @classmethod
    def _group_size_a_count(cls, options: dict[str, str | int | float | bool]) -> dict[str, str | int | float | bool]:
        """The agent places robots by it (isolation: agent); which isolations exist, the runner
        checks (fleet.server.units.launch_problem)."""
        size = options.get("group_size")
        if size is not None and not (isinstance(size, str) and size.isdigit() and size.isascii() and int(size) >= 1):
            raise ValueError(f"group_size must be a whole number of robots, at least 1, as text: got {size!r}")
        return options

    @model_validator(mode="after")
    def _entry_and_hot_files_exist(self) -> BundleMessage:
        if self.entry not in self.files:
            raise ValueError(f"entry {self.entry!r} is not among the bundle's files")
        for name in self.hot_files:
            if name not in self.files:
                raise ValueError(f"hot file {name!r} is not among the bundle's files")
        return self

    @property
    def hot_digest(self) -> str:
        return hot_digest(self.files, self.hot_files)

    @property
    def simulated(self) -> bool:
        """False for a real robot (`simulated: false` in the spec), whose data the world does not carry."""
        return simulated_option(self.options)

    def digest_matches(self) -> bool:
        """Whether `digest` is that of its files, entry and options: an agent decides what to
        restart by digests alone, so one that says less than its files would hide a change."""
        return self.digest == digest_of(cold_json(self.entry, self.options, self.files, self.hot_files))

    @classmethod
    def from_bundle(cls, bundle: Any) -> BundleMessage:
        return cls(
            name=bundle.name,
            kind=bundle.kind,
            entry=bundle.entry,
            files=dict(bundle.files),
            options=dict(bundle.options),
            hot_files=list(bundle.hot_files),
            digest=bundle.digest,
        )


MAX_ROUTES = 5000  # one way, per agent: the world's agent carries 3 for each robot elsewhere (render checks)


class TopicRoute(BaseModel):
    """One ROS topic a Zenoh bridge carries (on the wire in ApplyRequest.bridge)."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(pattern=rf"^(/{ROS_TOKEN_PATTERN}){{1,8}}$")
    type: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*/msg/[A-Za-z_][A-Za-z0-9_]*$")
    reliable: bool = True
    transient_local: bool = False
    depth: int = Field(10, ge=1, le=1000)


class BridgeRoutes(BaseModel):
    """What an agent's Zenoh bridge sends out (local ROS -> Zenoh) and brings in (Zenoh -> local ROS)."""

    model_config = ConfigDict(extra="forbid")

    exports: list[TopicRoute] = Field([], max_length=MAX_ROUTES)
    imports: list[TopicRoute] = Field([], max_length=MAX_ROUTES)


class ApplyRequest(Message):
    kind: Literal["apply"] = "apply"
    fleet: str
    agent: str
    generation: Generation
    domain_id: int = Field(ge=0, le=MAX_DOMAIN_ID)
    bundles: list[BundleMessage] = Field(max_length=MAX_BUNDLES)
    sent_at: float = 0.0
    # The fleet's DDS discovery server ("address:port") and the agent that runs it.  A host
    # without a server: the host was offline at the deploy, so its address was not known; it
    # serves at the address it reports and the other agents ask it for that.  Neither: the
    # fleet's ROS traffic stays on each agent's computer.
    discovery_server: str | None = None
    discovery_host: str | None = None
    # The `zenoh` transport: topics this agent's bridge carries over the fleet's Zenoh network.
    transport: Literal["dds", "zenoh"] = "dds"
    bridge: BridgeRoutes = BridgeRoutes()
    # Topics this agent's robots share (templates' share(...)): the agent watches their publishers.
    shared: list[TopicRoute] = Field([], max_length=MAX_ROUTES)
    has_world: bool = False  # whether the fleet has a world (StatusReply.has_world says it again)
    # Only ask whether the agent could run it (ApplyReply.problems), changing nothing: a deploy
    # asks every agent first, so that one robot's bad launch file leaves the whole fleet as it was.
    check_only: bool = False

    @field_validator("fleet", "agent")
    @classmethod
    def _names_are_key_chunks(cls, value: str) -> str:
        return _check_key_name(value)

    @field_validator("discovery_host")
    @classmethod
    def _host_is_key_chunk(cls, value: str | None) -> str | None:
        return None if value is None else _check_key_name(value)

    @field_validator("discovery_server")
    @classmethod
    def _server_is_address_and_port(cls, value: str | None) -> str | None:
        if value is not None and address_port_problem(value):
            raise ValueError(address_port_problem(value))
        return value

    def content_digest(self) -> str:
        """Hash of what this desired state asks for: equal on two requests when applying the one
        after the other changes nothing (the generation and the send time are left out; each
        bundle counts by its digests, which cover its files)."""
        content = self.model_dump(mode="json", exclude={"v", "kind", "generation", "sent_at", "bundles", "check_only"})
        content["bundles"] = [(bundle.name, bundle.digest, bundle.hot_digest) for bundle in self.bundles]
        return hashlib.sha256(json.dumps(content, sort_keys=True).encode()).hexdigest()

    @model_validator(mode="after")
    def _unique_bundle_names(self) -> ApplyRequest:
        names = [bundle.name for bundle in self.bundles]
        duplicates = sorted({name for name in names if names.count(name) > 1})
        if duplicates:
            raise ValueError(f"duplicate bundle names: {', '.join(duplicates)}")
        return self


class Changes(BaseModel):
    """What an apply does to the units of one agent, by robot name."""

    start: list[str] = []
    stop: list[str] = []
    restart: list[str] = []
    hot_update: list[str] = []
    unchanged: list[str] = []

    @property
    def nothing(self) -> bool:
        return not (self.start or self.stop or self.restart or self.hot_update)


class ApplyReply(Message):
    kind: Literal["apply_reply"] = "apply_reply"
    fleet: str
    agent: str
    generation: int
    accepted: bool
    current_generation: int  # the generation the agent holds after this request
    reason: str = ""  # why it was refused (e.g. superseded by a later generation)
    changes: Changes = Changes()
    problems: dict[str, str] = {}  # robot -> why its unit could not start here (check_only)


# ---------------------------------------------------------------------------------------------
# Status


class NodeState(BaseModel):
    name: str
    fqn: str = ""
    state: str  # as reported by the runner: starting, running, exited, failed, stopped, ...
    pid: int | None = None
    restarts: int = 0
    exit_code: int | None = None
    uptime: float | None = None
    ros: bool = False  # a ROS node (launch's `node`), not a plain executable: it joins the ROS graph
    # Whether this agent's watch of the fleet's ROS graph sees it there (None: not a ROS node, the
    # watch is not reporting, or a new watch has not found it yet and may still).
    in_graph: bool | None = None


RobotStateName = Literal["pending", "starting", "running", "degraded", "failed", "stopped"]


class RobotState(BaseModel):
    name: str
    kind: Literal["robot", "world"] = "robot"
    state: RobotStateName
    reason: str = ""  # why it is not running, in words, as its agent sees it (a node that ended, ...)
    nodes: list[NodeState] = []
    running: int = 0
    total: int = 0
    restarts: int = 0
    generation: int = 0  # the apply generation this unit last reconciled to
    # The generation of the deploy that brought the description it runs (0: unknown): a later
    # deploy that leaves it unchanged does not change it.
    deployed_generation: int = 0
    digest: str = ""
    hot_digest: str = ""
    overrides: dict[str, dict[str, Any]] = {}  # node -> parameter -> value set live
    error: str = ""
    # How many `fleet restart`s of it its agent has carried out (RestartReply.restart)
    restarted: int = 0
    simulated: bool = True  # False: a real robot, whose data the world does not carry


class AgentInfo(BaseModel):
    name: str
    hostname: str
    cores: int
    ros_distro: str = "jazzy"
    backends: list[str] = []
    pid: int
    version: str
    started_at: float
    address: str = ""  # where other computers reach this one (fleet agent --address)


# The world's state, as its process writes it to its status file (fleet/world/status.py describes
# the document).  These models read that file: unknown keys are ignored rather than refused, so a
# world that reports more than this side knows still shows, and cutting the document down to the
# status summary is just validating it with the smaller model (the bulky keys are skipped unread).


class WorldData(BaseModel):
    model_config = ConfigDict(extra="ignore")


class Pose(WorldData):
    x: float
    y: float
    yaw: float


class Velocity(WorldData):
    linear: float = 0.0
    angular: float = 0.0


class Contact(WorldData):
    sim_time: float
    a: str  # robot or obstacle names
    b: str
    kind: str  # robot-robot | robot-obstacle


class Contacts(WorldData):
    count: int = Field(0, ge=0)
    last: list[Contact] = []


class WorldProblem(WorldData):
    sim_time: float | None = None
    message: str


class WorldRobot(WorldData):
    pose: Pose
    velocity: Velocity | None = None
    battery: float | None = None  # fraction 0..1, None when no battery reports
    # Data flow as the world sees it: seconds since its last cmd_vel from the robot (None: never),
    # and how many subscriptions its odom publisher has matched (the robot's nodes, tools).
    cmd_age: float | None = None
    odom_subscribers: int | None = None


class WorldSummary(WorldData):
    """What `fleet status` needs of the world: small whatever the number of robots' histories."""

    sim_time: float = 0.0
    real_time_factor: float = 0.0
    age: float | None = None  # seconds since the world wrote this (set by its agent, same clock)
    robots: Mapping[str, WorldRobot] = {}
    contacts: Contacts = Contacts()
    errors: list[WorldProblem] = []


class RobotModel(WorldData):
    type: str
    radius: float | None = None
    length: float | None = None
    width: float | None = None


class WorldRobotFull(WorldRobot):
    model: RobotModel | None = None
    namespace: str | None = None
    trail: list[tuple[float, float]] = []
    scan_hits: list[tuple[float, float]] = []


class Obstacle(WorldData):
    name: str
    type: Literal["box", "cylinder"]
    position: tuple[float, float]
    yaw: float = 0.0
    size: list[float] | None = Field(None, min_length=2)  # boxes: [x, y, z]
    radius: float | None = None  # cylinders
    height: float | None = None

    @model_validator(mode="after")
    def _has_its_dimensions(self) -> Obstacle:
        if self.type == "cylinder" and self.radius is None:
            raise ValueError(f"obstacle {self.name!r}: a cylinder needs a radius")
        if self.type == "box" and self.size is None:
            raise ValueError(f"obstacle {self.name!r}: a box needs a size")
        return self


class WorldDocument(WorldSummary):
    """The whole status file: everything `fleet snapshot` draws (trails, lidar hits, obstacles)."""

    fleet: str = ""
    wall_time: float | None = None
    physics_rate: float | None = None
    robots: Mapping[str, WorldRobotFull] = {}
    obstacles: list[Obstacle] = []


STATUS_CONTACTS = 5  # contacts listed in a status reply (the world keeps more in its file)


def world_document(data: dict[str, Any]) -> WorldDocument:
    """The world status file, validated; raises ValueError with a readable reason."""
    try:
        return WorldDocument.model_validate(data)
    except ValidationError as error:
        raise ValueError(short_validation_error(error)) from None


def world_summary(document: dict[str, Any]) -> WorldSummary:
    """The world status file cut to the status reply's summary; raises ValueError when invalid."""
    try:
        summary = WorldSummary.model_validate(document)
    except ValidationError as error:
        raise ValueError(short_validation_error(error)) from None
    summary.contacts.last = summary.contacts.last[-STATUS_CONTACTS:]
    return summary


class SharedTopicState(BaseModel):
    """A shared topic's publishers as one agent sees them (fleet.dataplane.watch)."""

    name: str
    publishers: int = Field(ge=0)  # not counting the fleet's bridge
    silent: float | None = None  # seconds since a publisher was last seen; None while there is one
    age: float | None = None  # seconds since the watch last counted


class StatusReply(Message):
    kind: Literal["status"] = "status"
    agent: AgentInfo
    fleet: str | None  # None: the agent serves no fleet yet
    generation: int = 0  # desired (accepted) generation
    reconciled_generation: int = 0  # the generation the units have been brought to
    domain_id: int | None = None
    # The fleet's DDS discovery server when this agent runs it: "address:port", and its pid
    # (None while it is not running).
    discovery_server: str | None = None
    discovery_pid: int | None = None
    # The DDS discovery server this agent's robots of the fleet use ("address:port"; "": none,
    # their nodes stay on this computer); None when the reply is about no fleet.
    discovery_in_use: str | None = None
    bridge_pid: int | None = None  # this agent's Zenoh bridge of the fleet, when it runs one
    shared_topics: list[SharedTopicState] = []  # the shared topics this agent watches (fleet.dataplane.watch)
    robots: list[RobotState] = []
    world: WorldSummary | None = None  # when this agent runs the fleet's world and it has reported
    # Whether the fleet has a world (wherever it runs): its robots are judged by their data then,
    # even when no agent answering and no plan record says where the world is.
    has_world: bool = False
    # ApplyRequest.content_digest of the desired state held: a deploy that would send the same
    # to every agent has nothing to send ("" when the agent holds none for this fleet).
    content_digest: str = ""
    time: float


class WorldRequest(Message):
    """The world's full state (for `fleet snapshot`), from the agent running it."""

    kind: Literal["world"] = "world"
    fleet: str

    @field_validator("fleet")
    @classmethod
    def _fleet_is_key_chunk(cls, value: str) -> str:
        return _check_key_name(value)


class WorldReply(Message):
    kind: Literal["world_reply"] = "world_reply"
    fleet: str
    agent: str
    world: WorldDocument


# ---------------------------------------------------------------------------------------------
# Logs, restarts and parameters


class LogsRequest(Message):
    kind: Literal["logs"] = "logs"
    fleet: str
    robot: str
    node: str | None = None
    tail: int = Field(50, ge=0, le=MAX_LOG_LINES)
    # Follow mode: byte offset per node log already seen; None on the first request.
    cursor: dict[str, Annotated[int, Field(ge=0)]] | None = None


class LogLine(BaseModel):
    node: str
    text: str


class LogsReply(Message):
    kind: Literal["logs_reply"] = "logs_reply"
    lines: list[LogLine]
    cursor: dict[str, int]


class RestartRequest(Message):
    """Stop a robot's (or the world's) nodes and start them again, as they are deployed."""

    kind: Literal["restart"] = "restart"
    fleet: str
    robot: str

    @field_validator("fleet", "robot")
    @classmethod
    def _names_are_key_chunks(cls, value: str) -> str:
        return _check_key_name(value)


class RestartReply(Message):
    kind: Literal["restart_reply"] = "restart_reply"
    # The number of this restart: the robot's status shows `restarted` at least this once its
    # agent has stopped it and started it again.
    restart: int
    # AgentInfo.started_at of the agent process that counts it (0.0: not said): an agent started
    # again since counts from 0 and starts its robots anew.
    agent_started_at: float = 0.0


# How long an agent waits for a node's parameter service: a loaded host needs seconds for
# rclpy start-up and discovery.  A client waits this long plus the round trip.
PARAM_TIMEOUT = 30.0


class ParamRequest(Message):
    kind: Literal["param"] = "param"
    fleet: str
    robot: str
    node: str  # "" with op "list": every node of the robot
    name: str = Field("", max_length=200, pattern=r"^([A-Za-z_][A-Za-z0-9_.]*)?$")  # "" with op "list"
    op: Literal["get", "set", "list"]
    value: ParamValue | None = None

    @model_validator(mode="after")
    def _get_and_set_name_one_parameter(self) -> ParamRequest:
        if self.op != "list" and not (self.node and self.name):
            raise ValueError(f"a {self.op} needs a node and a parameter name")
        if self.op == "set" and self.value is None:
            raise ValueError("a set needs a value")
        return self


class ParamReply(Message):
    kind: Literal["param_reply"] = "param_reply"
    ok: bool
    value: ParamValue | None = None
    reason: str = ""
    # of a refusal: "not_found" when the node has no parameter of that name, REFUSED when the node
    # refuses the value (of another type, out of its range): both the asker's input
    code: str = ""
    note: str = ""  # of an accepted set that is not kept across restarts, and why
    # op "list": node -> parameter -> its value (None: a type fleet does not carry, a byte array),
    # node -> the parameters set live with `fleet param set` (kept until the robot changes), and
    # node -> why it did not answer
    parameters: dict[str, dict[str, ParamValue | None]] = {}
    set_live: dict[str, list[str]] = {}
    unanswered: dict[str, str] = {}


# ---------------------------------------------------------------------------------------------
# Router registry: what was deployed where, and which agents were seen when


class PlanRecord(Message):
    kind: Literal["plan"] = "plan"
    fleet: str
    generation: Generation
    robots: dict[str, str]  # robot (or "world") -> agent
    deployed_at: float


class AgentSeen(BaseModel):
    online: bool
    last_seen: float


class RegistryReply(Message):
    kind: Literal["registry"] = "registry"
    fleet: str
    plan: PlanRecord | None = None
    agents: dict[str, AgentSeen] = {}
    history: list[PlanRecord] = []  # the fleet's last deploys (and downs), oldest first


class DesiredQuery(Message):
    """An agent asking the router for its stored desired states (`fleet/*/desired/<agent>`).

    The router answers only those newer than what the agent holds, so the periodic ask is cheap;
    an empty one (`fleet down`) only for a fleet the agent holds."""

    kind: Literal["desired_query"] = "desired_query"
    held: dict[str, int] = {}  # fleet -> generation the agent holds


class DesiredDone(Message):
    """The router's reply, besides the states, to every DesiredQuery for any fleet
    (`fleet/*/desired/<agent>`, an agent's periodic ask; a query for one fleet gets only its
    state): the router heard the agent.  A query that gets no reply at all while the router is
    connected means the agent's session has stalled (fleet.server.agent replaces it)."""

    kind: Literal["desired_done"] = "desired_done"
    sent: int = Field(0, ge=0)  # desired states sent with it (Zenoh may deliver them after it)


class ErrorReply(Message):
    kind: Literal["error"] = "error"
    code: str
    error: str


# ---------------------------------------------------------------------------------------------
# Encoding


def encode(message: BaseModel) -> bytes:
    return message.model_dump_json().encode()


MessageT = TypeVar("MessageT", bound=Message)


def decode(payload: bytes | None, model: type[MessageT]) -> MessageT:
    """Parse and validate one message; raise ProtocolError with a readable reason."""
    return validate(parse(payload), model)


def parse(payload: bytes | None) -> dict[str, Any]:
    """The JSON object of one message of this protocol version (its "kind" still unchecked)."""
    if payload is None:
        raise ProtocolError("empty message", "malformed")
    if len(payload) > MAX_MESSAGE_BYTES:
        raise ProtocolError(f"message of {len(payload)} bytes exceeds {MAX_MESSAGE_BYTES}", "too_large")
    try:
        data = json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ProtocolError(f"malformed JSON (truncated?): {error}", "malformed") from None
    except RecursionError:
        raise ProtocolError("JSON nested too deeply", "malformed") from None
    if not isinstance(data, dict):
        raise ProtocolError("a message must be a JSON object", "malformed")
    if data.get("v") != VERSION:
        raise ProtocolError(f"unsupported protocol version {data.get('v')!r} (this side speaks {VERSION})", "version")
    return data


def validate(data: dict[str, Any], model: type[MessageT]) -> MessageT:
    """`model` from a parsed message; an error reply or another kind raises ProtocolError."""
    expected_kind = model.model_fields["kind"].default
    if data.get("kind") == "error" and model is not ErrorReply:
        try:
            reply = ErrorReply.model_validate(data)
        except ValidationError as error:
            raise ProtocolError(f"malformed error reply: {short_validation_error(error)}", "malformed") from None
        raise ProtocolError(reply.error, reply.code)
    if data.get("kind") != expected_kind:
        raise ProtocolError(f"expected a {expected_kind!r} message, got {data.get('kind')!r}", "malformed")
    try:
        return model.model_validate(data)
    except ValidationError as error:
        raise ProtocolError(short_validation_error(error), "invalid") from None


def short_validation_error(error: ValidationError) -> str:
    """The first few problems of `error`, one line: `name: String should match pattern ...`."""
    problems = []
    for item in error.errors()[:5]:
        where = ".".join(str(part) for part in item["loc"])
        message = validation_message(item)
        problems.append(f"{where}: {message}" if where else message)
    more = error.error_count() - len(problems)
    return "; ".join(problems) + (f" (and {more} more)" if more > 0 else "")


def error_reply(error: Exception) -> bytes:
    code = getattr(error, "code", "error")
    return encode(ErrorReply(code=code, error=str(error)))
