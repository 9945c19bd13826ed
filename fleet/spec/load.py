"""Load and validate a fleet spec: YAML -> FleetSpec, every problem reported with its place."""

from __future__ import annotations

import types
import typing
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from fleet.errors import Location, SpecError, did_you_mean, validation_message
from fleet.rules import (
    RESERVED_UNIT_NAMES,
    ROS_PARAMETERS_KEY,
    WORLD_TEMPLATE,
    key_name_problem,
    namespace_problem,
    node_key_problem,
    parameter_token_problem,
    ros_name_problem,
    template_name_problem,
)
from fleet.spec.model import FleetSpec
from fleet.spec.params import ParameterNameClash, flatten, namespace_clash, value_problem
from fleet.spec.yaml_source import DocPath, PathPattern, SourceMap, load_yaml, number_text_hint, read_input

# The mappings of a spec that hold a node's parameters: their values are typed as rcl types them.
PARAMETER_PATHS: tuple[PathPattern, ...] = (("robots", None, "parameters", None), ("defaults", "parameters", None))


def load_spec(path: str | Path) -> FleetSpec:
    """Read and validate the spec at `path`; raises SpecError naming file, line and problem."""
    path = Path(path)
    return parse_spec(read_input(path, "fleet spec"), str(path))


def parse_spec(text: str, file: str = "<spec>") -> FleetSpec:
    data, source = load_yaml(text, file, PARAMETER_PATHS)
    if not isinstance(data, dict):
        raise SpecError("a fleet spec is a mapping with at least 'fleet' and 'robots'", Location(file, 1, 1))
    try:
        spec = FleetSpec.model_validate(data)
    except ValidationError as error:
        raise _first_problem(error, source, data) from None
    spec._source_file = file
    spec._source_map = source
    check_spec(spec, source)
    return spec


def check_spec(spec: FleetSpec, source: SourceMap) -> None:
    """Rules that span fields: names, references between sections, parameter values."""

    def fail(message: str, path: DocPath, key: bool = False) -> None:
        raise SpecError(message, source.locate(path, key=key))

    if problem := key_name_problem(spec.fleet):
        fail(f"fleet name {problem}", ("fleet",))
    for agent in spec.agents:
        if problem := key_name_problem(agent):
            fail(f"agent name {problem}", ("agents", agent), key=True)

    def check_agent(name: str, path: DocPath) -> None:
        if name not in spec.agents:
            fail(f"agent {name!r} is not declared under 'agents' (declared: {', '.join(spec.agents) or 'none'})", path)

    if spec.world is not None and spec.world.agent is not None:
        check_agent(spec.world.agent, ("world", "agent"))
    # The first part of the fleet left to the default agent: where to say that it is not declared
    # when the spec does not name it (`defaults.agent` unwritten is `local`).
    unplaced = next((index for index, robot in enumerate(spec.robots) if robot.agent is None), None)
    if unplaced is not None:
        default_taker: tuple[str, DocPath] | None = (f"robot {spec.robots[unplaced].name!r}", ("robots", unplaced))
    elif spec.world is not None and spec.world.agent is None:
        default_taker = ("the world", ("world",))
    else:
        default_taker = None
    if default_taker is not None:
        if spec.defaults.agent not in spec.agents and "agent" not in spec.defaults.model_fields_set:
            what, path = default_taker
            first = next(iter(spec.agents), "...")
            fail(
                f"{what} names no agent, and the default one, {spec.defaults.agent!r}, is not declared under "
                f"'agents' (declared: {', '.join(spec.agents) or 'none'}): give it `agent: {first}`, or set "
                f"`defaults: {{agent: {first}}}`",
                path,
                key=path == ("world",),
            )
        check_agent(spec.defaults.agent, ("defaults", "agent"))

    def check_template(name: str | None, path: DocPath) -> None:
        if name is None:
            return
        if problem := template_name_problem(name):
            fail(f"template {problem}", path)
        if name == WORLD_TEMPLATE:
            fail(f"template {name!r} runs the fleet's shared world: a robot cannot use it", path)

    check_template(spec.defaults.template, ("defaults", "template"))
    check_parameters(spec.defaults.parameters, ("defaults", "parameters"), source)
    check_launch_args(spec.defaults.launch_args, ("defaults", "launch_args"), source)
    namespaces: dict[str, int] = {}
    seen: dict[str, int] = {}
    for index, robot in enumerate(spec.robots):
        here = ("robots", index)
        if problem := ros_name_problem(robot.name):
            fail(f"robot name {problem}", (*here, "name"))
        if robot.name in RESERVED_UNIT_NAMES:
            fail(
                f"robot name {robot.name!r} is reserved: the fleet's shared {robot.name} runs under that name, "
                "and the robot would overwrite its files",
                (*here, "name"),
            )
        check_template(robot.template, (*here, "template"))
        if robot.name in seen:
            fail(f"duplicate robot name {robot.name!r} (first defined as robots[{seen[robot.name]}])", (*here, "name"))
        seen[robot.name] = index
        namespace = robot.namespace or f"/{robot.name}"
        if robot.namespace is not None and (problem := namespace_problem(robot.namespace)):
            fail(f"robot {robot.name!r}: {problem}", (*here, "namespace"))
        if namespace in namespaces:
            fail(
                f"robot {robot.name!r} uses namespace {namespace} already used by robots[{namespaces[namespace]}]",
                (*here, "namespace") if robot.namespace else (*here, "name"),
            )
        namespaces[namespace] = index
        if robot.agent is not None:
            check_agent(robot.agent, (*here, "agent"))
        check_parameters(robot.parameters, (*here, "parameters"), source)
        check_launch_args(robot.launch_args, (*here, "launch_args"), source)
    check_capacity(spec, source)
    if spec.world is not None:
        names: set[str] = set()
        for index, obstacle in enumerate(spec.world.obstacles):
            if obstacle.name in names:
                fail(f"duplicate obstacle name {obstacle.name!r}", ("world", "obstacles", index, "name"))
            names.add(obstacle.name)


def check_capacity(spec: FleetSpec, source: SourceMap) -> None:
    """No agent gets more robots than its max_robots: the first robot over the limit is refused."""
    placed: dict[str, int] = {}
    for index, robot in enumerate(spec.robots):
        agent = robot.agent or spec.defaults.agent
        placed[agent] = placed.get(agent, 0) + 1
        limit = spec.agents[agent].max_robots if agent in spec.agents else placed[agent]
        if placed[agent] > limit:
            total = sum(1 for other in spec.robots if (other.agent or spec.defaults.agent) == agent)
            path = ("robots", index, "agent") if robot.agent else ("robots", index, "name")
            raise SpecError(
                f"robot {robot.name!r}: agent {agent!r} holds at most {limit} robots "
                f"(agents.{agent}.max_robots), the spec places {total} on it",
                source.locate(path),
            )


def check_launch_args(arguments: dict[str, Any], path: DocPath, source: SourceMap) -> None:
    """Launch argument values land in launch files, where `$(...)` is evaluated by `ros2 launch`
    (`$(command ...)` even runs a shell): such values are refused, never emitted."""
    for name, value in arguments.items():
        if problem := ros_name_problem(name):
            raise SpecError(f"launch argument name {problem}", source.locate((*path, name), key=True))
        if isinstance(value, str) and "$(" in value:
            raise SpecError(
                f"launch argument {name}: '$(' would be evaluated as a launch substitution; values must be plain text",
                source.locate((*path, name)),
            )


def check_parameters(parameters: dict[str, dict[str, Any]], path: DocPath, source: SourceMap) -> None:
    """Node names are ROS names; every (nested) parameter name is one, named once; every value is
    one ROS can hold."""
    for node, values in parameters.items():
        if problem := node_key_problem(node):
            raise SpecError(f"node name {problem}", source.locate((*path, node), key=True))
        check_node_parameters(node, values, (*path, node), source)


def check_node_parameters(node: str, values: dict[str, Any], path: DocPath, source: SourceMap) -> None:
    """Every (nested) parameter name of one node, whose parameters are at `path`, is a ROS name,
    named once; every value is one ROS can hold."""
    try:
        flat = flatten(values)
    except ParameterNameClash as clash:
        raise SpecError(
            f"parameter {node}.{clash.name} is written twice (as a dotted key and nested)",
            source.locate((*path, *clash.key_path), key=True),
        ) from None
    for name, (key_path, value) in flat.items():
        for key in key_path:
            if not isinstance(key, str):
                raise SpecError(
                    f"parameter name {key!r} in {node} must be text, not {type(key).__name__}",
                    source.locate((*path, *key_path), key=True),
                )
        for token in name.split("."):
            if problem := parameter_token_problem(token):
                # at the key that holds the token (`ros__parameters:` above the parameters)
                depth = next(i for i, key in enumerate(key_path, 1) if token in key.split("."))
                raise SpecError(
                    f"parameter name {node}.{name}: {problem}",
                    source.locate((*path, *key_path[:depth]), key=True),
                )
        if problem := value_problem(value):
            raise SpecError(f"parameter {node}.{name}: {problem}", source.locate((*path, *key_path)))
    if overlap := namespace_clash(flat):
        raise SpecError(
            f"{node}.{overlap[0]} is both a parameter and the namespace of {node}.{overlap[1]}: ROS cannot hold both",
            source.locate((*path, *flat[overlap[1]][0]), key=True),
        )


# rcl reads a node's name from the keys above its `ros__parameters`: `/robot1/controller:`, or
# one key per namespace level (`robot1: {controller: ...}`); a file fleet did not write may nest.
_MAX_NAME_LEVELS = 8
_PARAMETER_FILE_PATHS: tuple[PathPattern, ...] = tuple(
    (*[None] * levels, ROS_PARAMETERS_KEY) for levels in range(1, _MAX_NAME_LEVELS + 1)
)


def check_parameter_file(text: str, file: str) -> None:
    """A ROS parameter file as rcl reads it (`/robot1/controller: {ros__parameters: {...}}`):
    SpecError, located, for what would stop a node that reads it at start."""
    data, source = load_yaml(text, file, _PARAMETER_FILE_PATHS)
    if data is None:
        return
    if not isinstance(data, dict):
        raise SpecError("a parameter file maps node names to their parameters", Location(file, 1))
    _check_name_level(data, (), source)


def _check_name_level(level: dict[Any, Any], path: DocPath, source: SourceMap) -> None:
    """One level of node names of a parameter file: each key a name, below it the node's
    `ros__parameters` or the next level of its name."""
    for key, below in level.items():
        here = (*path, key)
        if not isinstance(key, str) or not key:
            raise SpecError(f"node name {key!r} is not a name", source.locate(here, key=True))
        node = "/".join(str(part) for part in here)
        if not isinstance(below, dict) or not below:
            raise SpecError(
                f"{node}: expected the node's {{{ROS_PARAMETERS_KEY}: {{...}}}}", source.locate(here, key=True)
            )
        for name, value in below.items():
            if name != ROS_PARAMETERS_KEY:
                if len(here) >= _MAX_NAME_LEVELS:
                    raise SpecError(
                        f"{node}: no {ROS_PARAMETERS_KEY} within {_MAX_NAME_LEVELS} levels",
                        source.locate(here, key=True),
                    )
                _check_name_level({name: value}, here, source)
            elif isinstance(value, dict):
                check_node_parameters(node, value, (*here, name), source)
            else:
                raise SpecError(
                    f"{node}: {ROS_PARAMETERS_KEY} must map parameter names to values", source.locate((*here, name))
                )


def _first_problem(error: ValidationError, source: SourceMap, data: Any) -> SpecError:
    """Turn pydantic's first error into one line with the place it refers to."""
    # A misspelt key also makes the key it should have been "missing": report the typo first.
    problems = error.errors()
    problem = next((p for p in problems if p["type"] == "extra_forbidden"), problems[0])
    loc = _data_path(problem["loc"], data)
    kind = problem["type"]
    where = ".".join(str(p) if not isinstance(p, int) else f"[{p}]" for p in loc).replace(".[", "[")
    if kind == "extra_forbidden":
        unknown = loc[-1]
        allowed = _fields_at(loc[:-1])
        message = f"unknown key {unknown!r}" + (f" in {_parent(loc)}" if loc[:-1] else "")
        message += did_you_mean(str(unknown), allowed) or f" (allowed: {', '.join(allowed)})"
        return SpecError(message, source.locate(loc, key=True))
    if kind in ("tuple_type", "too_long") or (kind == "missing" and isinstance(problem["loc"][-1], int)):
        # A tuple of the schema (position, size), written as a YAML list: pydantic reports a short
        # one as its first absent item "missing", which would read as the key itself missing.
        got = problem["input"]
        count = f"a list of {len(got)}" if isinstance(got, tuple) else _describe(got)
        return SpecError(f"{where}: must be a list of {_tuple_length(loc)} numbers, got {count}", source.locate(loc))
    if kind == "missing":
        return SpecError(
            f"missing required key {loc[-1]!r}" + (f" in {_parent(loc)}" if loc[:-1] else ""), source.locate(loc[:-1])
        )
    if kind == "too_short" and loc == ("robots",):
        return SpecError("robots: a fleet needs at least one robot", source.locate(loc))
    if kind == "invalid_key" or problem["loc"][-1] == "[key]":
        # A key YAML 1.1 read as something else (yes, on, 5): pydantic says where by its value.
        key = problem["input"]
        at = loc if problem["loc"][-1] == "[key]" else (*loc[:-1], key)
        in_parent = f" in {_parent(at)}" if at[:-1] else ""
        return SpecError(
            f"key {_describe(key)}{in_parent}: keys here are names, written as text (quote it)",
            source.locate(at, key=True),
        )
    message = validation_message(problem)
    if kind.endswith("_type") or kind in ("literal_error", "too_short"):
        got = _as_written(problem.get("input"), loc, data)
        if kind != "too_short":
            message = f"{message}, got {_describe(got)}"
    return SpecError(f"{where}: {message}" if where else message, source.locate(loc))


def _as_written(value: Any, loc: DocPath, data: Any) -> Any:
    """The value at `loc` as the spec has it: the models see integers as floats (_ints_to_floats),
    so pydantic's `5.0` was the user's `5`."""
    for part in loc:
        try:
            data = data[part]
        except (KeyError, IndexError, TypeError):
            return value
    return data if data == value else value


def _data_path(loc: tuple[Any, ...], data: Any) -> DocPath:
    """The path in the document of pydantic's error location: the keys and indexes found in the
    data, without the parts pydantic adds for union branches and validators (`int`,
    `function-after[...]`), which a user's key may look like."""
    path = []
    for part in loc:
        found = (isinstance(data, dict) and part in data) or (
            isinstance(data, (list, tuple)) and isinstance(part, int) and 0 <= part < len(data)
        )
        if found:
            data = data[part]
        elif isinstance(data, dict) and isinstance(part, str) and "[" not in part and part not in _BRANCHES:
            data = None  # a key the data lacks: a missing one, reported in its parent
        else:
            continue
        path.append(part)
    return tuple(path)


# Union branch names pydantic puts in error locations (the types of a launch argument's value).
_BRANCHES = {"bool", "int", "float", "str", "tuple", "list", "dict", "none"}


def _parent(loc: DocPath) -> str:
    parts = [str(p) if not isinstance(p, int) else f"[{p}]" for p in loc[:-1]]
    return ".".join(parts).replace(".[", "[")


def _describe(value: Any) -> str:
    if hint := number_text_hint(value):
        return f"string {value!r} ({hint})"
    if isinstance(value, str):
        return f"string {value!r}"
    if value is None:
        return "null"
    if isinstance(value, (dict, list)):
        return type(value).__name__.replace("dict", "mapping")
    return f"{type(value).__name__} {value!r}"


def _annotation_at(loc: DocPath) -> Any:
    """The type the spec schema declares at `loc`."""
    annotation: Any = FleetSpec
    for part in loc:
        model = _model_in(annotation)
        if model is not None and isinstance(part, str) and part in model.model_fields:
            annotation = model.model_fields[part].annotation
            continue
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        annotation = args[-1] if args else annotation
    return annotation


def _fields_at(loc: DocPath) -> list[str]:
    """Field names of the model found at `loc` in the spec schema (for did-you-mean)."""
    model = _model_in(_annotation_at(loc))
    if model is None:
        return []
    return [name for name, field in model.model_fields.items() if not field.exclude]


def _tuple_length(loc: DocPath) -> int:
    """How many items the tuple declared at `loc` (`tuple[float, float]`, maybe `| None`) has."""
    annotation = _annotation_at(loc)
    if typing.get_origin(annotation) is not tuple:
        annotation = next(a for a in typing.get_args(annotation) if typing.get_origin(a) is tuple)
    return len(typing.get_args(annotation))


def _model_in(annotation: Any) -> type[BaseModel] | None:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        for arg in typing.get_args(annotation):
            if isinstance(arg, type) and issubclass(arg, BaseModel):
                return arg
    return None
