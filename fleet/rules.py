"""Rules shared by every stage: names, reserved names, file names, the state directory's layout, respawns.

Robot names become ROS namespaces, agent and fleet names become Zenoh key parts and file names.
Dependency-free (the standard library only), so the spec, the wire protocol, the agent and the
CLI all read the same rule without paying for one another's imports.
"""

from __future__ import annotations

import os
import re
import typing
from pathlib import Path
from typing import Literal

# ROS 2 name tokens (rmw_validate_node_name / namespace tokens): letters, digits, underscores,
# not starting with a digit.
ROS_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")  # one part of a ROS name (any length)
# Zenoh key chunks must not contain / * $ ? # and we keep them boring on purpose.
_KEY_CHUNK = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
MAX_NAME_LENGTH = 63
# One token of a ROS name, length bound included: for patterns elsewhere (pydantic fields).
ROS_TOKEN_PATTERN = rf"[A-Za-z_][A-Za-z0-9_]{{0,{MAX_NAME_LENGTH - 1}}}"
# rmw (validate_full_topic_name.h): a fully qualified topic or service name has at most 255 - 8
# characters, 8 being reserved for the DDS prefixes; a namespace 2 fewer (validate_namespace.h),
# room for the shortest name in it.  Both checked with rclpy's validators.
MAX_TOPIC_NAME_LENGTH = 247
MAX_NAMESPACE_LENGTH = MAX_TOPIC_NAME_LENGTH - 2
# Every ROS node serves its parameters under its own name; the longest of those services is the
# longest name a node creates, so it bounds how long a node's full name can be.
LONGEST_NODE_SERVICE = "set_parameters_atomically"
MAX_DOMAIN_ID = 232  # ROS 2's highest ROS_DOMAIN_ID on Linux (its DDS ports stay below the ephemeral range)

# The units an agent runs besides robots, by name.  A robot cannot take one of these names: a
# robot named `world` would be the world's unit and overwrite its files.
WORLD_UNIT = "world"
RESERVED_UNIT_NAMES = frozenset({WORLD_UNIT})
# The template of the world unit: no robot can run it.
WORLD_TEMPLATE = "world"
# The agent the local daemon (`fleet up`) runs, and the one a spec gets when it names none.
LOCAL_AGENT = "local"


# A node process that ran this long is healthy again: the runner's respawn backoff starts over,
# and a deploy counts a respawned node as up only from then on.
STABLE_AFTER = 10.0
MIN_BACKOFF = 0.25  # base of the exponential backoff when respawn_delay is 0
MAX_BACKOFF = 30.0


def backoff_delay(respawn_delay: float, failures_in_row: int) -> float:
    """How long a node that failed waits to be started again, in the runner's processes and in a
    host alike: the first respawn waits respawn_delay (as launch does); each further quick failure
    doubles the wait, up to MAX_BACKOFF (or respawn_delay if that is larger)."""
    if failures_in_row <= 1:
        return respawn_delay
    base = max(respawn_delay, MIN_BACKOFF)
    # The exponent capped: 2.0 ** 1024 overflows, after some 8 hours of a node failing at once.
    return min(max(MAX_BACKOFF, respawn_delay), base * 2.0 ** min(failures_in_row - 1, 64))


# -- the simulated world's defaults and limits, one rule for the spec's `world`, robots' `model` and
# `lidar`, and world.yaml (fleet.spec.model and fleet.world.description both hold them) ------------
DEFAULT_PHYSICS_RATE = 240.0  # Hz
DEFAULT_ODOM_RATE = 50.0  # Hz of each robot's odometry
DEFAULT_CMD_TIMEOUT = 0.5  # s a robot's last command holds
# A robot's simulated body: `light` (a planar one-body diff drive, cheap) or a URDF of pybullet_data.
ModelType = Literal["light", "husky", "racecar"]
MODEL_TYPES: tuple[str, ...] = typing.get_args(ModelType)
DEFAULT_MODEL_TYPE: ModelType = "light"
DEFAULT_MODEL_RADIUS = 0.2  # m, the light model's footprint
DEFAULT_LINEAR_SPEED = 1.0  # m/s, a model's top speed
DEFAULT_ANGULAR_SPEED = 2.5  # rad/s
ObstacleKind = Literal["box", "wall", "cylinder"]
OBSTACLE_TYPES: tuple[str, ...] = typing.get_args(ObstacleKind)
# A robot's lidar.
DEFAULT_BEAMS = 360
DEFAULT_LIDAR_RATE = 10.0  # Hz
DEFAULT_RANGE_MIN = 0.12  # m
DEFAULT_RANGE_MAX = 8.0  # m
MAX_PHYSICS_RATE = 2000.0  # Hz
MAX_TOPIC_RATE = 1000.0  # Hz of /clock, a robot's odometry or its lidar
MAX_CMD_TIMEOUT = 60.0  # s a robot's last command holds
MAX_BEAMS = 4096  # of a lidar
MAX_LIDAR_RANGE = 1000.0  # m
MAX_MODEL_RADIUS = 5.0  # m, of the light model's footprint
MAX_LINEAR_SPEED = 20.0  # m/s
MAX_ANGULAR_SPEED = 50.0  # rad/s


def daemon_agents(extra: list[str] | tuple[str, ...] = ()) -> list[str]:
    """The agents a local daemon runs: `local`, then those `fleet up --agent` named, once each."""
    return list(dict.fromkeys([LOCAL_AGENT, *extra]))


# ---------------------------------------------------------------------------------------------
# File names of a bundle and of the templates

LAUNCH_SUFFIX = ".launch.yaml"  # the launch file a unit runs (its entry)
PYTHON_LAUNCH_SUFFIX = ".launch.py"  # the same description as a Python launch file
PARAMS_SUFFIX = ".params.yaml"  # a robot's ROS parameters; beside a template: its defaults
TEMPLATE_SUFFIX = ".launch.yaml.j2"
# The world unit's description of its world (fleet/world/description.py reads it; the world
# re-reads it as it changes), and its status file beside it (templates/world.launch.yaml.j2).
WORLD_DESCRIPTION = "world.yaml"
WORLD_STATUS_FILE = "world.status.json"
# A bundle's option, False for a real robot's only (`simulated: false`): left out for every other
# unit, so that their digests stay as they were (fleet.wire.protocol.simulated_option reads it).
SIMULATED_OPTION = "simulated"

# ---------------------------------------------------------------------------------------------
# The state directory ($FLEET_STATE_DIR or ~/.local/state/fleet) of the local daemon:
#
#     daemon.pid  daemon.log       the daemon process and its log (router and agent)
#     router/registry.json         what was deployed where (fleet.server.router)
#     agents/<agent>/              an agent's own state directory, below
#
# An agent's state directory:
#
#     agent.json                   name of the agent owning the directory
#     desired/<fleet>.json         the accepted desired state plus live parameter overrides
#     units/<fleet>/<robot>/       bundle files as written for the runner, logs/ beside them
#     hosts/<fleet>-<n>/           logs of the host processes of `isolation: agent`
#     services/<fleet>.*           the fleet's discovery server and Zenoh bridge: config, logs

STATE_VARIABLE = "FLEET_STATE_DIR"


def state_dir() -> Path:
    """Absolute: the daemon's agents leave the working directory for their own (a relative
    FLEET_STATE_DIR had the daemon's router write its registry under the agent's directory).
    Refused (FleetError) where no directory can be."""
    value = os.environ.get(STATE_VARIABLE)
    path = Path(os.path.abspath(Path(value).expanduser())) if value else Path.home() / ".local" / "state" / "fleet"
    if problem := directory_problem(path):
        from fleet.errors import FleetError, Location

        raise FleetError(f"state directory (${STATE_VARIABLE}) {problem}", Location(path))
    return path


def directory_problem(path: Path) -> str | None:
    """Why no directory can be at `path` (it is a file, or a file is where a directory above it
    would be), or None: it is one, or it can be made."""
    for place in (path, *path.parents):
        if place.exists():
            if place.is_dir():
                return None
            where = "is" if place == path else f"cannot be made: {place} is"
            return f"{where} a file, not a directory"
    return None


def daemon_pid_file(root: Path) -> Path:
    return root / "daemon.pid"


def daemon_log_file(root: Path) -> Path:
    return root / "daemon.log"


def router_dir(root: Path) -> Path:
    return root / "router"


def registry_file(router: Path) -> Path:
    """The registry file in a router's state directory."""
    return router / "registry.json"


def agent_dir(root: Path, agent: str) -> Path:
    return root / "agents" / agent


def agent_marker_file(agent: Path) -> Path:
    return agent / "agent.json"


def desired_dir(agent: Path) -> Path:
    return agent / "desired"


def units_dir(agent: Path) -> Path:
    return agent / "units"


def unit_dir(agent: Path, fleet: str, robot: str) -> Path:
    return units_dir(agent) / fleet / robot


UNIT_LOG_DIR = "logs"  # in a unit's directory, beside its bundle's files
# What else than its bundle's files a unit's directory holds: no bundle file may take these names.
UNIT_OWN_NAMES = frozenset({UNIT_LOG_DIR, WORLD_STATUS_FILE})


def unit_log_dir(unit: Path) -> Path:
    return unit / UNIT_LOG_DIR


def services_dir(agent: Path) -> Path:
    return agent / "services"


def hosts_root(agent: Path) -> Path:
    """Where an agent's host pools (isolation: agent) keep their logs, one directory each."""
    return agent / "hosts"


def hosts_dir(agent: Path, fleet: str, number: int) -> Path:
    return hosts_root(agent) / f"{fleet}-{number}"


def ros_name_problem(name: object) -> str | None:
    """Why `name` is not a valid ROS node/robot name (or namespace or topic token), or None if it
    is.  Node names and namespaces reach the node as remap rules (`-r __node:=name`, `-r
    __ns:=/ns`, as launch_ros passes them), which rcl refuses to parse when a token holds '__'."""
    problem = _token_problem(name)
    if problem is None and "__" in str(name):
        return f"{name!r} is not a valid ROS name: '__' is reserved (rcl reads it in __ns, __node)"
    return problem


def _token_problem(name: object) -> str | None:
    """Why `name` is not one token of letters, digits and underscores, or None."""
    if not isinstance(name, str):
        return f"must be a string, not {type(name).__name__}"
    if not name:
        return "must not be empty"
    if len(name) > MAX_NAME_LENGTH:
        return f"is longer than {MAX_NAME_LENGTH} characters"
    if not ROS_TOKEN.fullmatch(name):
        if name[0].isdigit():
            return f"{name!r} is not a valid ROS name: it must not start with a digit"
        return f"{name!r} is not a valid ROS name: use letters, digits and underscores only"
    return None


# The key a ROS parameter file puts between a node's name and its parameters.  fleet writes it
# itself; given in a spec, a template's defaults or --set, it is a file copied in ROS's own form,
# and rcl would read its values as parameters named `ros__parameters.<name>`, which no node has.
ROS_PARAMETERS_KEY = "ros__parameters"


def parameter_token_problem(token: object) -> str | None:
    """Why `token` cannot be one dot-separated token of a parameter's name, or None."""
    if token == ROS_PARAMETERS_KEY:
        return f"{ROS_PARAMETERS_KEY!r} is fleet's to write: give them right under the node (controller: {{x: 1.0}})"
    return _token_problem(token)  # read from a parameter file, never from a remap rule: '__' is fine


def node_key_problem(name: object) -> str | None:
    """Why `name` cannot name a node in a robot's parameters, or None: a node's name
    (`controller`), or the name relative to the robot's namespace of a node that runs inside
    another node's process (`local_costmap/local_costmap`), each token a ROS name."""
    if not isinstance(name, str) or "/" not in name:
        return ros_name_problem(name)
    if name.startswith("/"):
        return f"{name!r} must be relative to the robot's namespace (no leading '/')"
    for token in name.split("/"):
        if problem := ros_name_problem(token):
            return f"{name!r}: token {problem}"
    return None


def namespace_problem(namespace: object) -> str | None:
    """Why `namespace` is not a valid absolute ROS namespace like /site_a/robot1, or None."""
    if not isinstance(namespace, str):
        return f"must be a string, not {type(namespace).__name__}"
    if not namespace.startswith("/") or namespace == "/":
        return f"{namespace!r} must be an absolute namespace such as '/robot1'"
    if len(namespace) > MAX_NAMESPACE_LENGTH:
        return f"namespace of {len(namespace)} characters: ROS namespaces have at most {MAX_NAMESPACE_LENGTH}"
    for token in namespace[1:].split("/"):
        problem = ros_name_problem(token)
        if problem:
            return f"namespace {namespace!r}: token {problem}"
    return None


def key_name_problem(name: object) -> str | None:
    """Why `name` cannot be a fleet or agent name (used in Zenoh keys and file names), or None."""
    if not isinstance(name, str):
        return f"must be a string, not {type(name).__name__}"
    if not _KEY_CHUNK.fullmatch(name) or len(name) > MAX_NAME_LENGTH:
        return (
            f"{name!r} is not a valid name: use letters, digits, '_', '-', '.' (not first), at most {MAX_NAME_LENGTH}"
        )
    return None


def node_name_problem(fqn: str) -> str | None:
    """Why a node of this full name (/robot1/controller) could not start: ROS names are bounded."""
    longest = f"{fqn}/{LONGEST_NODE_SERVICE}"
    if len(longest) > MAX_TOPIC_NAME_LENGTH:
        return (
            f"node {fqn} would serve {longest[:40]}..., {len(longest)} characters: "
            f"ROS names have at most {MAX_TOPIC_NAME_LENGTH} (use a shorter namespace)"
        )
    return None


def template_name_problem(name: object) -> str | None:
    """Why `name` cannot name a template, or None: a plain name, looked up only inside the
    template directories (never a path)."""
    if not isinstance(name, str):
        return f"must be a string, not {type(name).__name__}"
    if not _KEY_CHUNK.fullmatch(name) or ".." in name or len(name) > MAX_NAME_LENGTH:
        return (
            f"{name!r} is not a template name: a plain name of letters, digits, '_', '-', '.' "
            "found in the templates directory, not a path"
        )
    return None


def service_node_name(service: str, fleet: str) -> str:
    """The ROS node name of a fleet's service process on an agent (`bridge`: its Zenoh bridge,
    `watch`: its shared topic watch, fleet.dataplane): a fleet name's '-' and '.' are not
    allowed in node names."""
    return f"fleet_{service}_{fleet.replace('-', '_').replace('.', '_')}"


def topic_name_problem(name: object) -> str | None:
    """Why `name` cannot name a topic a template shares, or None: absolute (`/fleet/announcements`,
    fleet-wide) or relative to the robot's namespace (`pose`, `sensors/pose`), each token a ROS
    name.  Private (`~/x`) and substitution (`{node}`) names need a node, and a shared topic has
    none, so they are refused."""
    if not isinstance(name, str):
        return f"must be a string, not {type(name).__name__}"
    if not name or name == "/":
        return "must not be empty"
    if name.startswith("~") or "{" in name:
        return f"{name!r}: private (~) and substituted ({{...}}) names are relative to a node; a shared topic has none"
    relative = name.removeprefix("/")
    if relative.endswith("/") or "//" in name:
        return f"{name!r} is not a valid ROS topic name: empty token (a doubled or trailing '/')"
    for token in relative.split("/"):
        if problem := ros_name_problem(token):
            return f"{name!r}: token {problem}"
    return None


def resolve_topic_name(name: str, namespace: str) -> str:
    """The full name of topic `name` (already checked by topic_name_problem) as a node in
    `namespace` would resolve it: absolute names stay, relative ones go below the namespace."""
    return name if name.startswith("/") else f"{namespace.rstrip('/')}/{name}"


# A name token as rcl's lexer reads a remap rule (rcl/src/rcl/arguments.c, lexer.c): letters,
# digits and underscores, not starting with a digit, no '__' anywhere ('__ns' and the like are
# lexemes of their own).  No length bound at parse time.
_REMAP_TOKEN = re.compile(r"(?!.*__)[A-Za-z_][A-Za-z0-9_]*")
_REMAP_SCHEMES = ("rostopic://", "rosservice://")
_REMAP_NAME_RULE = (
    "tokens of letters, digits and underscores, not starting with a digit and without '__', "
    "joined by '/', optionally after '/' or '~/'"
)


def _remap_name_problem(name: str, side: str) -> str | None:
    relative = name.removeprefix("~/") if name.startswith("~/") else name.removeprefix("/")
    if all(_REMAP_TOKEN.fullmatch(token) for token in relative.split("/")):
        return None
    return f"{side} {name!r} is not a ROS name ({_REMAP_NAME_RULE})"


def remap_problem(source: str, target: str) -> str | None:
    """Why a node could not start with the remap rule `-r source:=target` (launch_ros passes a
    remap's `from` and `to` so), or None: rcl refuses the whole command line over a rule it
    cannot parse.  What rcl accepts: `[node:][rostopic://|rosservice://]name:=name` with names
    plain, absolute (`/a/b`) or private (`~/a`); `[node:]__node:=token` (also `__name`) and
    `[node:]__ns:=/absolute/namespace`.  Checked against rclpy's own parse (tests)."""
    match = source
    prefix, colon, rest = source.partition(":")
    if colon and not source.startswith(_REMAP_SCHEMES):
        if not _REMAP_TOKEN.fullmatch(prefix):
            return f"from {source!r}: {prefix!r} before ':' is not a node name"
        match = rest
    scheme = next((scheme for scheme in _REMAP_SCHEMES if match.startswith(scheme)), "")
    match = match.removeprefix(scheme)
    if not scheme and match in ("__node", "__name"):
        if not _REMAP_TOKEN.fullmatch(target):
            return f"to {target!r} is not a node name (letters, digits and underscores, not starting with a digit)"
        return None
    if not scheme and match == "__ns":
        tokens = target.removesuffix("/").split("/")
        if target != "/" and (tokens[0] != "" or not all(_REMAP_TOKEN.fullmatch(token) for token in tokens[1:])):
            return f"to {target!r} is not an absolute namespace such as /robot1"
        return None
    return _remap_name_problem(match, "from") or _remap_name_problem(target, "to")


# What follows `--ros-args` on a node's command line, as rcl parses it (rcl/src/rcl/arguments.c):
# rcl refuses the whole command line over a value it cannot parse, and rclpy and rclcpp refuse
# arguments they do not know; either way the node does not start.  Checked against rclpy (tests).
_ROS_FLAGS = frozenset(
    f"--{switch}-{logs}-logs" for switch in ("enable", "disable") for logs in ("rosout", "stdout", "external-lib")
)
_ROS_OPTIONS = frozenset(
    {"-r", "--remap", "-p", "--param", "--params-file", "--log-level", "-e", "--enclave", "--log-file-name"}
)
LOG_LEVELS = ("debug", "info", "warn", "error", "fatal", "unset")  # rcutils' severities, any case
# rclpy.init arguments of fleet's own ROS helpers (parameter calls, graph watch, bridge): no
# /rosout, and no rcl log file, which rcl would otherwise create for each of their processes
# (one per `fleet param` command) in ~/.ros/log, where nothing ever removes it.
HELPER_ROS_ARGS = ("--ros-args", "--disable-rosout-logs", "--disable-external-lib-logs")


def ros_arguments_problem(arguments: list[str]) -> str | None:
    """Why a node could not start with this command line's ROS arguments (those after each
    `--ros-args`, up to `--`), or None."""
    in_ros = False
    index = 0
    while index < len(arguments):
        argument = arguments[index]
        index += 1
        if argument in ("--ros-args", "--"):
            in_ros = argument == "--ros-args"
        elif not in_ros or argument in _ROS_FLAGS:
            continue
        elif argument == "--log-config-file":
            return "--log-config-file: Jazzy's logging backend (spdlog) takes no configuration file"
        elif argument not in _ROS_OPTIONS:
            return f"{argument!r} is not a ROS argument (rclpy and rclcpp refuse unknown ones after --ros-args)"
        elif index == len(arguments):
            return f"{argument} needs a value after it"
        else:
            if problem := _ros_option_problem(argument, arguments[index]):
                return problem
            index += 1
    return None


def _ros_option_problem(option: str, value: str) -> str | None:
    if option in ("-r", "--remap"):
        source, assign, target = value.partition(":=")
        return remap_problem(source, target) if assign else f"{option} {value!r}: a remap rule is from:=to"
    if option in ("-p", "--param"):
        name, assign, given = value.partition(":=")
        return None if assign and name and given else f"{option} {value!r}: a parameter override is name:=value"
    if option == "--log-level":
        logger, assign, level = value.rpartition(":=")
        if (assign and not logger) or level.lower() not in LOG_LEVELS:
            return f"--log-level {value!r}: give a level ({', '.join(LOG_LEVELS)}) or logger:=level"
    if option in ("-e", "--enclave") and not value.startswith("/"):
        return f"{option} {value!r}: an enclave is an absolute name such as /fleet/robot1"
    return None


# ---------------------------------------------------------------------------------------------
# ROS parameter types


def ros_type(value: object) -> str:
    """The ROS parameter type of a Python value, as rclpy names it
    (rclpy.Parameter.Type.from_parameter_value(value).name.lower())."""
    if value is None:
        return "not_set"
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "double"
    if isinstance(value, str):
        return "string"
    if isinstance(value, (list, tuple)):
        # rclpy tries bytes, bool, int, float and str in turn; a list's first item rules out the
        # others (an empty list is all of them: bytes first).
        for item_type, name in _ARRAY_TYPES if not value else _ARRAY_TYPES_OF.get(type(value[0]), _ARRAY_TYPES):
            if all(isinstance(item, item_type) for item in value):
                return name
    return type(value).__name__


_ARRAY_TYPES = (
    (bytes, "byte_array"),
    (bool, "bool_array"),
    (int, "integer_array"),
    (float, "double_array"),
    (str, "string_array"),
)
# A list's first item's type -> the array types it can be, in rclpy's order (True is an int too).
_ARRAY_TYPES_OF = {
    item_type: tuple(entry for entry in _ARRAY_TYPES if issubclass(item_type, entry[0]))
    for item_type in (bytes, bool, int, float, str)
}
