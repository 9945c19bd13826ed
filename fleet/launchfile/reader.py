"""Launch file text to a LaunchDescription, refusing (with file:line:col) whatever the embedded
runner cannot run, and saying when `ros2 launch` would run it.

Every action, attribute and substitution is checked here, in every branch (also those a
condition will skip), so a file is refused before anything starts.  Attribute types follow the
frontends (fleet.launchfile.entities): launch_yaml does not convert, so a string attribute must be
a YAML string (`respawn: 'true'`, not `true`); a file accepted here also runs under `ros2 launch`.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

import yaml

from fleet.errors import LaunchFileError, Location, NeedsRos2Launch, SpecError, did_you_mean
from fleet.launchfile import description as d
from fleet.launchfile.entities import XML, YAML, Entity, xml_actions, yaml_actions, yaml_document_actions
from fleet.launchfile.substitutions import Ros2OnlySubstitution, SubstitutionSyntax, Text, literal, parse_substitutions
from fleet.spec.yaml_source import SourceMap, read_input

_CONDITION = {"if", "unless"}
_PROCESS = {"env", "respawn", "respawn_delay", "output", "name"}
# Attributes (and sub-entity lists) of each action the embedded runner runs.
ATTRIBUTES: dict[str, set[str]] = {
    "arg": {"name", "default", "description", "choice"},
    "let": {"name", "value"},
    "set_env": {"name", "value"},
    "unset_env": {"name"},
    "push_ros_namespace": {"namespace"},
    "push-ros-namespace": {"namespace"},
    "group": {"children", "scoped", "forwarding", "keep"},
    "include": {"file", "arg"},
    "timer": {"period", "children"},
    "log": {"message"},
    "set_parameter": {"name", "value"},
    "set_remap": {"from", "to"},
    "executable": _PROCESS | {"cmd", "cwd"},
    "node": _PROCESS | {"pkg", "exec", "namespace", "exec_name", "param", "remap", "args", "ros_args"},
}
# Actions and attributes launch Jazzy also knows: refused with a pointer to the ros2 backend.
ROS2_ACTIONS = {
    "append_env",
    "reset_env",
    "reset",
    "shutdown",
    "ros_timer",
    "load_composable_node",
    "node_container",
    "set_parameters_from_file",
    "set_ros_log_dir",
    "set_use_sim_time",
}
ROS2_ATTRIBUTES = {
    "executable": {
        "launch-prefix",
        "shell",
        "emulate_tty",
        "sigterm_timeout",
        "sigkill_timeout",
        "on_exit",
        "respawn_max_retries",
    },
    "node": {
        "launch-prefix",
        "shell",
        "emulate_tty",
        "sigterm_timeout",
        "sigkill_timeout",
        "on_exit",
        "respawn_max_retries",
        "cwd",
        "node-name",
    },
    "timer": {"cancel_on_shutdown"},
}
_NEEDS_ROS2 = "needs the ros2 backend (--backend ros2)"


def read_launch_file(path: Path) -> d.LaunchDescription:
    path = Path(path).absolute()
    try:
        text = read_input(path, "launch")  # first: a file that is not there is said to be missing
    except SpecError as problem:  # worded as for every input file: "no such launch file", ...
        raise LaunchFileError(problem.message, problem.location) from None
    if path.name.endswith(".py"):
        raise NeedsRos2Launch(
            "a Python launch file runs only under `ros2 launch`: it " + _NEEDS_ROS2 + "; the embedded runner "
            "reads .launch.yaml and .launch.xml files",
            Location(path),
        )
    return read_launch_text(text, path)


def read_launch_text(text: str, path: Path) -> d.LaunchDescription:
    name = path.name
    if name.endswith((".yaml", ".yml")):
        entities = yaml_actions(text, str(path))
    elif name.endswith(".xml"):
        entities = xml_actions(text, str(path))
    else:
        raise NeedsRos2Launch(
            "the embedded runner reads YAML (.launch.yaml) and XML (.launch.xml) launch files; "
            "run other launch files with `ros2 launch` (--backend ros2)",
            Location(path),
        )
    return d.LaunchDescription(path, [_action(entity) for entity in entities])


def read_launch_document(data: Any, source: SourceMap, path: Path) -> d.LaunchDescription:
    """The description of a YAML launch document the caller has loaded (load_yaml) for its own
    use too, so the text is parsed once."""
    return d.LaunchDescription(path, [_action(entity) for entity in yaml_document_actions(data, source, str(path))])


def _text(entity: Entity, name: str) -> Text:
    """A string attribute, parsed for substitutions."""
    value = entity.attributes()[name]
    if not isinstance(value, str):
        raise LaunchFileError(
            f"'{name}' of '{entity.kind}' must be a string (quote it: '{value}'); "
            "ros2 launch does not convert YAML values",
            entity.where_of(name),
        )
    return _parse(value, entity.where_of(name))


def _parse(value: str, where: Location) -> Text:
    try:
        return parse_substitutions(value)
    except SubstitutionSyntax as problem:
        error = NeedsRos2Launch if isinstance(problem, Ros2OnlySubstitution) else LaunchFileError
        raise error(str(problem), where) from None


def _optional_text(entity: Entity, name: str) -> Text | None:
    return _text(entity, name) if name in entity.attributes() else None


def _required(entity: Entity, name: str) -> None:
    if name not in entity.attributes():
        raise LaunchFileError(f"action '{entity.kind}' needs '{name}'", entity.where)


def _check_keys(entity: Entity, allowed: set[str]) -> None:
    for key in entity.attributes():
        if key in allowed:
            continue
        if key in ROS2_ATTRIBUTES.get(entity.kind, set()):
            raise NeedsRos2Launch(f"attribute '{key}' of '{entity.kind}' {_NEEDS_ROS2}", entity.where_of(key))
        listed = ", ".join(sorted(allowed))
        raise LaunchFileError(f"unknown key '{key}' in '{entity.kind}' (allowed: {listed})", entity.where_of(key))


def _boolean(entity: Entity, name: str, default: bool) -> bool | Text:
    """A bool attribute.  launch_yaml checks only that it is a bool *or a string* and passes a
    string on as it is, where launch tests its truth: `scoped: 'false'` is a non-empty string,
    so the group IS scoped under ros2 launch.  That oddity is kept (the string is returned and
    taken for its truth).  launch_xml converts 'true'/'false'/'1'/'0' and keeps other strings."""
    value = entity.attributes().get(name, default)
    if isinstance(value, bool):
        return value
    if not isinstance(value, str):
        raise LaunchFileError(f"'{name}' of '{entity.kind}' must be true or false", entity.where_of(name))
    if entity.frontend == XML and value.lower() in ("true", "false", "1", "0"):
        return value.lower() in ("true", "1")
    return (value,)


def _float(entity: Entity, name: str, default: float, substitutions: bool) -> float | Text:
    value = entity.attributes().get(name, default)
    if entity.frontend == XML and isinstance(value, str):
        with contextlib.suppress(ValueError):  # launch_xml keeps what is not a number as text
            value = float(value)
    if isinstance(value, float) and value >= 0.0:
        return value
    if substitutions and isinstance(value, str):
        return _parse(value, entity.where_of(name))
    raise LaunchFileError(
        f"'{name}' of '{entity.kind}' must be a non-negative float (write 2.0, not 2: ros2 launch does not convert)",
        entity.where_of(name),
    )


def _condition(entity: Entity) -> d.Condition | None:
    attributes = entity.attributes()
    if "if" in attributes and "unless" in attributes:
        raise LaunchFileError(f"'if' and 'unless' cannot both be used on '{entity.kind}'", entity.where)
    for keyword in ("if", "unless"):
        if keyword in attributes:
            return d.Condition(keyword, _text(entity, keyword))
    return None


def _pairs(entity: Entity, name: str, first: str, second: str) -> list[tuple[Text, Text]]:
    result = []
    for item in entity.entities(name) or []:
        _check_keys(item, {first, second})
        _required(item, first)
        _required(item, second)
        result.append((_text(item, first), _text(item, second)))
    return result


def _children(entity: Entity) -> list[d.Action]:
    children = entity.children()
    if children is None:
        raise LaunchFileError(f"'{entity.kind}' needs a list of actions ('children')", entity.where)
    return [_action(child) for child in children if not (entity.frontend == XML and child.kind == "keep")]


def _action(entity: Entity) -> d.Action:
    kind = entity.kind
    if kind in ROS2_ACTIONS:
        raise NeedsRos2Launch(f"action '{kind}' {_NEEDS_ROS2}", entity.where)
    if kind not in ATTRIBUTES:
        hint = did_you_mean(kind, [*ATTRIBUTES, *ROS2_ACTIONS])
        raise LaunchFileError(f"unknown action '{kind}'{hint}", entity.where)
    body_is_list = entity.frontend == YAML and isinstance(getattr(entity, "body", None), list)
    if not body_is_list and entity.frontend == YAML and not isinstance(getattr(entity, "body", None), dict):
        raise LaunchFileError(f"action '{kind}' needs a mapping of attributes", entity.where)
    if body_is_list and kind not in ("group", "timer"):
        raise LaunchFileError(f"action '{kind}' needs a mapping of attributes", entity.where)
    allowed = set(ATTRIBUTES[kind]) | _CONDITION
    if entity.frontend == XML and kind in ("group", "timer"):
        allowed |= {child.kind for child in entity.children() or []}
    _check_keys(entity, allowed)
    condition = _condition(entity)
    for name in _REQUIRED.get(kind, ()):
        _required(entity, name)
    where = entity.where
    if kind == "arg":
        return _argument(entity, where, condition)
    if kind == "let":
        return d.SetConfiguration(where, condition, _text(entity, "name"), _text(entity, "value"))
    if kind == "set_env":
        return d.SetEnv(where, condition, _text(entity, "name"), _text(entity, "value"))
    if kind == "unset_env":
        return d.UnsetEnv(where, condition, _text(entity, "name"))
    if kind in ("push_ros_namespace", "push-ros-namespace"):
        return d.PushNamespace(where, condition, _text(entity, "namespace"))
    if kind == "group":
        return d.Group(
            where,
            condition,
            _children(entity),
            scoped=_boolean(entity, "scoped", True),
            forwarding=_forwarding(entity),
            keep=_pairs(entity, "keep", "name", "value"),
        )
    if kind == "include":
        return d.Include(where, condition, _text(entity, "file"), _pairs(entity, "arg", "name", "value"))
    if kind == "timer":
        return d.Timer(where, condition, _float(entity, "period", 0.0, substitutions=True), _children(entity))
    if kind == "log":
        return d.Log(where, condition, _text(entity, "message"))
    if kind == "set_parameter":
        # launch_ros reads the value as substitution text (a string attribute), typed as YAML once
        # substituted, even when it holds no substitution: `value: 'true'` is the bool true here,
        # unlike a node's own `param`.
        return d.SetParameter(where, condition, _text(entity, "name"), _text(entity, "value"))
    if kind == "set_remap":
        return d.SetRemap(where, condition, _text(entity, "from"), _text(entity, "to"))
    env = _pairs(entity, "env", "name", "value")
    respawn = _optional_text(entity, "respawn")
    delay = _float(entity, "respawn_delay", 0.0, substitutions=False)
    assert isinstance(delay, float)  # substitutions=False
    output = _optional_text(entity, "output")
    process_name = _optional_text(entity, "name")
    if kind == "executable":
        return d.Executable(
            where,
            condition,
            env,
            respawn,
            delay,
            output,
            process_name,
            cmd=_text(entity, "cmd"),
            cwd=_optional_text(entity, "cwd"),
        )
    return d.Node(
        where,
        condition,
        env,
        respawn,
        delay,
        output,
        process_name,
        package=_text(entity, "pkg"),
        executable=_text(entity, "exec"),
        namespace=_optional_text(entity, "namespace"),
        exec_name=_optional_text(entity, "exec_name"),
        params=_params(entity),
        remaps=_pairs(entity, "remap", "from", "to"),
        args=_optional_text(entity, "args"),
        ros_args=_optional_text(entity, "ros_args"),
    )


_REQUIRED = {
    "arg": ("name",),
    "let": ("name", "value"),
    "set_env": ("name", "value"),
    "unset_env": ("name",),
    "push_ros_namespace": ("namespace",),
    "push-ros-namespace": ("namespace",),
    "include": ("file",),
    "timer": ("period",),
    "log": ("message",),
    "set_parameter": ("name", "value"),
    "set_remap": ("from", "to"),
    "executable": ("cmd",),
    "node": ("pkg", "exec"),
}


def _forwarding(entity: Entity) -> bool:
    forwarding = _boolean(entity, "forwarding", True)
    if forwarding is not True:
        # A group that starts from an empty scope (forwarding false) is rare in practice.
        raise NeedsRos2Launch(f"'forwarding' other than true {_NEEDS_ROS2}", entity.where_of("forwarding"))
    return True


def _argument(entity: Entity, where: Location, condition: d.Condition | None) -> d.DeclareArgument:
    name = entity.attributes()["name"]
    if not isinstance(name, str):
        raise LaunchFileError("'name' of 'arg' must be a string", entity.where_of("name"))
    description = entity.attributes().get("description")
    if description is not None and not isinstance(description, str):
        raise LaunchFileError("'description' of 'arg' must be a string", entity.where_of("description"))
    choices = None
    items = entity.entities("choice")
    if items is not None:
        values = []
        for item in items:
            _check_keys(item, {"value"})
            _required(item, "value")
            value = item.attributes()["value"]
            if not isinstance(value, str):
                raise LaunchFileError("a choice 'value' must be a string", item.where_of("value"))
            values.append(value)
        choices = tuple(values)
    default = _optional_text(entity, "default")
    if choices is not None and default is not None:
        literal_default = "".join(part for part in default if isinstance(part, str))
        if len(default) <= 1 and literal_default not in choices:
            raise LaunchFileError(
                f"default '{literal_default}' of argument '{name}' is not one of its choices ({', '.join(choices)})",
                entity.where_of("default"),
            )
    return d.DeclareArgument(where, condition, name, default, description, choices)


def _param_value(entity: Entity) -> Any:
    value = entity.attributes()["value"]
    where = entity.where_of("value")
    if isinstance(value, str):
        return _parse(value, where)
    if isinstance(value, bool | int | float):
        return value
    if isinstance(value, list) and value and all(isinstance(item, bool | int | float | str) for item in value):
        return [_parse(item, where) if isinstance(item, str) else item for item in value]
    raise LaunchFileError(
        f"a parameter value must be a bool, int, float, string or a non-empty list of those (got {value!r})", where
    )


def _params(entity: Entity) -> list[d.ParamFile | d.InlineParam]:
    result: list[d.ParamFile | d.InlineParam] = []
    for item in entity.entities("param") or []:
        keys = set(item.attributes())
        if "from" in keys:
            _check_keys(item, {"from"})
            result.append(d.ParamFile(_text(item, "from"), item.where))
        else:
            result.append(_inline_param(item))
    return result


def _inline_param(item: Entity) -> d.InlineParam:
    keys = set(item.attributes())
    if "type" in keys:
        raise NeedsRos2Launch(f"parameter attribute 'type' {_NEEDS_ROS2}", item.where_of("type"))
    _check_keys(item, {"name", "value", "param"})
    _required(item, "name")
    nested = item.entities("param")
    if nested is not None:
        if "value" in keys:
            raise LaunchFileError("a parameter has either a 'value' or nested 'param's, not both", item.where)
        return d.InlineParam(_text(item, "name"), [_inline_param(child) for child in nested], item.where, nested=True)
    if "value" not in keys:
        raise LaunchFileError(
            "a node 'param' item is either {from: FILE} or {name: N, value: V} (or nested 'param's)", item.where
        )
    value = item.attributes()["value"]
    if item.frontend == XML:
        return d.InlineParam(_text(item, "name"), _xml_value(value, item.where_of("value")), item.where)
    return d.InlineParam(_text(item, "name"), _param_value(item), item.where)


def _xml_value(value: str, where: Location) -> Any:
    """launch_xml types a value by YAML rules (an XML attribute is always text); one that holds
    substitutions is typed the same way once substituted (by launch_ros)."""
    text = _parse(value, where)
    if literal(text) is None or value == "":
        return text
    try:
        typed = yaml.safe_load(value)
    except yaml.YAMLError:
        return value  # launch_xml keeps what YAML cannot read as text
    if isinstance(typed, bool | int | float | str):
        return typed
    if isinstance(typed, list) and typed and all(isinstance(item, bool | int | float | str) for item in typed):
        return typed
    raise LaunchFileError(f"parameter value '{value}' is not a bool, int, float, string or list of those", where)
