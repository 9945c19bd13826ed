"""Read a ROS 2 YAML launch file (the subset fleet renders) into launch_ros-identical commands.

The embedded runner must start nodes exactly as `ros2 launch` would (see DESIGN.md, "How
launch_ros starts a node").  Reading happens in two passes, both before anything starts:

1. `_Reader` turns the YAML into action objects, checking every action, key, type and
   substitution name, in every branch (also the ones a condition will skip), with line numbers.
2. `_Interpreter` executes them in order like launch does: conditions, launch configurations
   (`arg`, `let`), scoped groups, pushed namespaces, `set_env`, substitutions, and drafts one
   `NodeLaunch` per node.

Only then are the inline parameters written to temporary files (launch_ros does the same) and
the command lines assembled.  Attribute types follow launch_yaml, which does not coerce: an
attribute launch reads as a string must be a YAML string (`respawn: 'true'`, not `true`), so a
file accepted here also runs under `ros2 launch`.
"""

from __future__ import annotations

import os
import re
import shlex
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fleet.errors import FleetError, LaunchFileError, Location, SpecError
from fleet.runtime import ament
from fleet.spec.yaml_source import SourceMap, YamlSyntaxError, load_yaml

# ---------------------------------------------------------------------------------------------
# Results


@dataclass
class NodeLaunch:
    """One node, as launch_ros would start it."""

    name: str | None  # node name given in the file; None: the executable's default
    namespace: str | None  # absolute; None when neither the node nor a group gives one
    package: str
    executable: str
    cmd: list[str]  # the full command line, executable path first
    env: dict[str, str] = field(default_factory=dict)  # set_env variables in effect
    respawn: bool = False
    respawn_delay: float = 0.0
    output: str = "log"  # screen | log | both
    process_name: str = ""  # launch's process name: `<exe>-<n>`, the prefix of screen lines
    location: Location | None = None

    @property
    def fqn(self) -> str | None:
        """Full node name (`/robot1/controller`), when the name is known."""
        if self.name is None:
            return None
        namespace = self.namespace or "/"
        return namespace.rstrip("/") + "/" + self.name

    @property
    def ros_arguments(self) -> list[str]:
        """Everything after the executable (what `composite --fleet-node EXE` gets)."""
        return self.cmd[1:]


@dataclass
class LaunchPlan:
    path: Path
    arguments: dict[str, str]  # launch arguments (declared and given) and their values
    nodes: list[NodeLaunch]


# ---------------------------------------------------------------------------------------------
# YAML with line numbers


class _Map(dict[Any, Any]):
    """A YAML mapping that remembers where it and each of its keys start (1-based lines).
    _with_lines makes every mapping one."""

    line: int | None = None
    key_lines: dict[Any, int]


def _with_lines(value: Any, path: tuple, source: SourceMap) -> Any:
    """`value` (data from load_yaml) with each mapping a _Map holding its lines from `source`."""
    if isinstance(value, dict):
        result = _Map()
        result.line = source.positions[path][0]
        result.key_lines = {}
        for key, item in value.items():
            result[key] = _with_lines(item, (*path, key), source)
            result.key_lines[key] = source.key_positions[(*path, key)][0]
        return result
    if isinstance(value, list):
        return [_with_lines(item, (*path, index), source) for index, item in enumerate(value)]
    return value


# ---------------------------------------------------------------------------------------------
# Substitutions: `$(var X)`, `$(env X)`, `$(env X DEFAULT)`, `$(dirname)`, `$(find-pkg-share P)`


@dataclass(frozen=True)
class _Subst:
    kind: str
    args: tuple  # tuple of parts (each a tuple of str | _Subst)


_Parts = tuple  # tuple[str | _Subst, ...]

_ARITY = {"var": (1, 1), "env": (1, 2), "dirname": (0, 0), "find-pkg-share": (1, 1)}


class _SubstitutionSyntax(Exception):
    pass


def _parse_parts(text: str, start: int, inside: bool) -> tuple[list, int]:
    """Parse text (or one substitution argument when `inside`) into literal and _Subst parts."""
    parts: list = []
    literal: list[str] = []
    index = start
    quote: str | None = None
    while index < len(text):
        char = text[index]
        if text.startswith("$(", index):
            if literal:
                parts.append("".join(literal))
                literal = []
            subst, index = _parse_subst(text, index + 2)
            parts.append(subst)
            continue
        if inside:
            if quote is not None:
                if char == quote:
                    quote = None
                    index += 1
                    continue
            elif char in "'\"":
                quote = char
                index += 1
                continue
            elif char.isspace() or char == ")":
                break
        literal.append(char)
        index += 1
    if quote is not None:
        raise _SubstitutionSyntax(f"unterminated quote in {text!r}")
    if literal:
        parts.append("".join(literal))
    return parts, index


def _parse_subst(text: str, index: int) -> tuple[_Subst, int]:
    """Parse `name args...)` starting after `$(`; return the substitution and the index after `)`."""
    match = re.compile(r"\s*([A-Za-z][A-Za-z0-9_-]*)").match(text, index)
    if match is None:
        raise _SubstitutionSyntax(f"substitution without a name in {text!r}")
    kind = match.group(1)
    index = match.end()
    args = []
    while True:
        while index < len(text) and text[index].isspace():
            index += 1
        if index >= len(text):
            raise _SubstitutionSyntax(f"unterminated substitution '$({kind}' in {text!r}")
        if text[index] == ")":
            index += 1
            break
        arg, index = _parse_parts(text, index, inside=True)
        args.append(tuple(arg))
    if kind not in _ARITY:
        supported = ", ".join(f"$({name})" for name in _ARITY)
        raise _SubstitutionSyntax(f"unknown substitution '$({kind})' (the embedded runner supports {supported})")
    low, high = _ARITY[kind]
    if not low <= len(args) <= high:
        raise _SubstitutionSyntax(f"'$({kind})' takes {low}..{high} arguments, got {len(args)}")
    return _Subst(kind, tuple(args)), index


def parse_substitutions(text: str) -> _Parts:
    parts, _ = _parse_parts(text, 0, inside=False)
    return tuple(parts)


# ---------------------------------------------------------------------------------------------
# Pass 1: actions


@dataclass
class _Condition:
    keyword: str  # if | unless
    parts: _Parts


@dataclass
class _Action:
    line: int | None
    condition: _Condition | None


@dataclass
class _Arg(_Action):
    name: str
    default: _Parts | None


@dataclass
class _Let(_Action):
    name: _Parts
    value: _Parts


@dataclass
class _SetEnv(_Action):
    name: _Parts
    value: _Parts


@dataclass
class _PushNamespace(_Action):
    namespace: _Parts


@dataclass
class _Group(_Action):
    actions: list
    scoped: _Parts | bool


@dataclass
class _ParamFile:
    path: _Parts
    line: int | None


@dataclass
class _InlineParam:
    name: _Parts
    value: Any  # parts, a scalar, or a list of parts/scalars
    line: int | None


@dataclass
class _Node(_Action):
    package: _Parts
    executable: _Parts
    name: _Parts | None
    namespace: _Parts | None
    params: list[_ParamFile | _InlineParam]
    remaps: list[tuple[_Parts, _Parts]]
    args: _Parts | None
    ros_args: _Parts | None
    respawn: _Parts | None
    respawn_delay: float
    output: _Parts | None


_COMMON_KEYS = {"if", "unless"}
_NODE_KEYS = {
    "pkg",
    "exec",
    "name",
    "namespace",
    "param",
    "remap",
    "args",
    "ros_args",
    "respawn",
    "respawn_delay",
    "output",
}
_ACTION_KEYS = {
    "arg": {"name", "default", "description"},
    "let": {"name", "value"},
    "set_env": {"name", "value"},
    "push_ros_namespace": {"namespace"},
    "group": {"children", "scoped"},
    "node": _NODE_KEYS,
}


def _line(error: FleetError) -> int | None:
    return error.location.line if error.location is not None else None


class _Reader:
    """Pass 1: YAML data to action objects, refusing anything outside the supported subset."""

    def __init__(self, path: Path):
        self.path = path

    def error(self, message: str, line: int | None) -> LaunchFileError:
        return LaunchFileError(message, Location(self.path, line))

    def read(self, text: str) -> list:
        from fleet.spec.yaml_source import safe_load

        try:
            safe_load(text, self.path)  # the limits of every fleet input first: depth, aliases, tags, numbers
        except SpecError as problem:
            raise LaunchFileError(f"invalid YAML: {problem.message}", problem.location) from None
        try:
            loaded, source = load_yaml(text, self.path)
        except YamlSyntaxError as problem:
            raise self.error(f"invalid YAML: {problem.problem}", _line(problem)) from None
        except SpecError as problem:  # duplicate keys and the like, worded by the reader
            raise self.error(problem.message, _line(problem)) from None
        source.locate(())  # the reader finds places only when first asked: every line is needed here
        data = _with_lines(loaded, (), source)
        if not isinstance(data, _Map) or set(data) != {"launch"}:
            raise self.error("a launch file is a mapping with the single key 'launch'", 1)
        actions = data["launch"]
        if not isinstance(actions, list):
            raise self.error("'launch' must be a list of actions", data.key_lines["launch"])
        return self.actions(actions, data.key_lines["launch"])

    def actions(self, items: list, line: int | None) -> list:
        result = []
        for item in items:
            if not isinstance(item, _Map) or len(item) != 1:
                raise self.error(
                    "each action is a mapping with exactly one key, the action type",
                    getattr(item, "line", line),
                )
            kind, body = next(iter(item.items()))
            result.append(self.action(kind, body, item.key_lines[kind]))
        return result

    def action(self, kind: Any, body: Any, line: int) -> _Action:
        if kind not in _ACTION_KEYS:
            supported = ", ".join(sorted(_ACTION_KEYS))
            raise self.error(f"unknown action '{kind}' (the embedded runner supports {supported})", line)
        if kind == "group" and isinstance(body, list):
            body = _Map(children=body)
            body.line, body.key_lines = line, {"children": line}
        if not isinstance(body, _Map):
            raise self.error(f"action '{kind}' needs a mapping of attributes", line)
        body_line = body.line or line
        unknown = set(body) - _ACTION_KEYS[kind] - _COMMON_KEYS
        if unknown:
            key = sorted(unknown, key=str)[0]
            allowed = ", ".join(sorted(_ACTION_KEYS[kind] | _COMMON_KEYS))
            raise self.error(
                f"unknown key '{key}' in action '{kind}' (allowed: {allowed})",
                body.key_lines.get(key, body_line),
            )
        condition = self.condition(kind, body)
        attrs = _Attributes(self, kind, body)
        if kind == "arg":
            return _Arg(line, condition, attrs.string("name", substitutions=False), attrs.optional("default"))
        if kind == "let":
            return _Let(line, condition, attrs.parts("name"), attrs.parts("value"))
        if kind == "set_env":
            return _SetEnv(line, condition, attrs.parts("name"), attrs.parts("value"))
        if kind == "push_ros_namespace":
            return _PushNamespace(line, condition, attrs.parts("namespace"))
        if kind == "group":
            children = body.get("children")
            if not isinstance(children, list):
                raise self.error("'group' needs a list of actions ('children')", body_line)
            scoped = attrs.boolean("scoped", default=True)
            return _Group(line, condition, self.actions(children, body_line), scoped)
        return self.node(line, condition, attrs, body)

    def condition(self, kind: str, body: _Map) -> _Condition | None:
        if "if" in body and "unless" in body:
            raise self.error(f"'if' and 'unless' cannot both be used on '{kind}'", body.line)
        for keyword in ("if", "unless"):
            if keyword in body:
                attrs = _Attributes(self, kind, body)
                return _Condition(keyword, attrs.parts(keyword))
        return None

    def node(self, line: int, condition: _Condition | None, attrs: _Attributes, body: _Map) -> _Node:
        delay = body.get("respawn_delay", 0.0)
        if "respawn_delay" in body and (not isinstance(delay, float) or delay < 0.0):
            raise self.error(
                "'respawn_delay' of 'node' must be a non-negative float (write 2.0, not 2: "
                "ros2 launch does not convert)",
                body.key_lines["respawn_delay"],
            )
        return _Node(
            line,
            condition,
            package=attrs.parts("pkg"),
            executable=attrs.parts("exec"),
            name=attrs.optional("name"),
            namespace=attrs.optional("namespace"),
            params=self.params(body),
            remaps=self.remaps(body),
            args=attrs.optional("args"),
            ros_args=attrs.optional("ros_args"),
            respawn=attrs.optional("respawn"),
            respawn_delay=float(delay),
            output=attrs.optional("output"),
        )

    def _items(self, body: _Map, key: str) -> list[_Map]:
        items = body.get(key, [])
        if not isinstance(items, list) or not all(isinstance(item, _Map) for item in items):
            raise self.error(f"'{key}' of 'node' must be a list of mappings", body.key_lines[key])
        return items

    def params(self, body: _Map) -> list[_ParamFile | _InlineParam]:
        result: list[_ParamFile | _InlineParam] = []
        for item in self._items(body, "param"):
            keys = set(item)
            attrs = _Attributes(self, "param", item)
            if keys == {"from"}:
                result.append(_ParamFile(attrs.parts("from"), item.line))
            elif keys == {"name", "value"}:
                value = self.param_value(item["value"], item.key_lines["value"])
                result.append(_InlineParam(attrs.parts("name"), value, item.line))
            else:
                raise self.error(
                    "a node 'param' item is either {from: FILE} or {name: N, value: V}; "
                    f"got keys {sorted(keys, key=str)}",
                    item.line,
                )
        return result

    def param_value(self, value: Any, line: int) -> Any:
        if isinstance(value, str):
            return self.substitutions(value, line)
        if isinstance(value, (bool, int, float)):
            return value
        if isinstance(value, list) and value and all(isinstance(element, (bool, int, float, str)) for element in value):
            return [self.param_value(element, line) for element in value]
        raise self.error(
            f"a parameter value must be a bool, int, float, string or a non-empty list of those (got {value!r})",
            line,
        )

    def remaps(self, body: _Map) -> list[tuple[_Parts, _Parts]]:
        result = []
        for item in self._items(body, "remap"):
            if set(item) != {"from", "to"}:
                raise self.error(
                    f"a node 'remap' item is {{from: NAME, to: NAME}}; got keys {sorted(item, key=str)}",
                    item.line,
                )
            attrs = _Attributes(self, "remap", item)
            result.append((attrs.parts("from"), attrs.parts("to")))
        return result

    def substitutions(self, text: str, line: int | None) -> _Parts:
        try:
            return parse_substitutions(text)
        except _SubstitutionSyntax as problem:
            raise self.error(str(problem), line) from None


class _Attributes:
    """Typed access to an action's attributes, with launch_yaml's (non-coercing) type rules."""

    def __init__(self, reader: _Reader, kind: str, body: _Map):
        self.reader, self.kind, self.body = reader, kind, body

    def _line(self, key: str) -> int | None:
        return self.body.key_lines.get(key, self.body.line)

    def string(self, key: str, substitutions: bool = True) -> Any:
        if key not in self.body:
            raise self.reader.error(f"action '{self.kind}' needs '{key}'", self.body.line)
        value = self.body[key]
        if not isinstance(value, str):
            raise self.reader.error(
                f"'{key}' of '{self.kind}' must be a string (quote it: '{value}'); "
                "ros2 launch does not convert YAML values",
                self._line(key),
            )
        return self.reader.substitutions(value, self._line(key)) if substitutions else value

    def parts(self, key: str) -> _Parts:
        return self.string(key)

    def optional(self, key: str) -> _Parts | None:
        return self.string(key) if key in self.body else None

    def boolean(self, key: str, default: bool) -> _Parts | bool:
        value = self.body.get(key, default)
        if isinstance(value, bool):
            return value
        return self.string(key)


# ---------------------------------------------------------------------------------------------
# Pass 2: execution


@dataclass
class _Scope:
    """What a scoped group saves and restores: launch configurations, environment, namespace."""

    configurations: dict[str, str]
    env: dict[str, str]  # set_env variables
    namespace: str | None

    def copy(self) -> _Scope:
        return _Scope(dict(self.configurations), dict(self.env), self.namespace)


@dataclass
class _NodeDraft:
    """A node before its inline parameters are written: params are ('file', path) or
    ('inline', key, {name: value})."""

    launch: NodeLaunch
    executable_path: Path
    arguments: list[str]
    ros_arguments: list[str] | None
    params: list[tuple]
    remaps: list[tuple[str, str]]


_NAME_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _prefix_namespace(base: str | None, namespace: str | None) -> str | None:
    """A relative namespace is appended to the base; an absolute one replaces it."""
    if namespace is None:
        combined = base
    elif not base or namespace.startswith("/"):
        combined = namespace
    else:
        combined = ("" if base == "/" else base) + "/" + namespace
    if combined is not None and combined != "/":
        combined = combined.rstrip("/")
    return combined


def _absolute(namespace: str | None) -> str | None:
    if namespace is None or namespace.startswith("/"):
        return namespace
    return "/" + namespace


def _valid_namespace(namespace: str) -> bool:
    if namespace == "/":
        return True
    tokens = namespace.split("/")
    return tokens[0] == "" and all(_NAME_TOKEN.fullmatch(token) for token in tokens[1:])


class _Interpreter:
    """Pass 2: run the actions like launch does and draft the nodes."""

    def __init__(self, path: Path, launch_args: Mapping[str, str], env: Mapping[str, str], search_path: str):
        self.path = path
        self.base_env = env
        self.search_path = search_path
        self.launch_args = dict(launch_args)
        self.arguments: dict[str, str] = {}
        self.drafts: list[_NodeDraft] = []

    def error(self, message: str, line: int | None) -> LaunchFileError:
        return LaunchFileError(message, Location(self.path, line))

    def run(self, actions: list) -> list[_NodeDraft]:
        # Launch arguments given on the command line are launch configurations even when the
        # file does not declare them (as with `ros2 launch`).
        scope = _Scope(dict(self.launch_args), {}, None)
        self.arguments.update(self.launch_args)
        self.execute(actions, scope)
        return self.drafts

    # -- substitutions --

    def resolve(self, parts: _Parts, scope: _Scope, line: int | None) -> str:
        return "".join(self.resolve_part(part, scope, line) for part in parts)

    def resolve_part(self, part: str | _Subst, scope: _Scope, line: int | None) -> str:
        if isinstance(part, str):
            return part
        args = [self.resolve(arg, scope, line) for arg in part.args]
        if part.kind == "var":
            if args[0] not in scope.configurations:
                raise self.error(f"launch configuration '{args[0]}' is not defined", line)
            return scope.configurations[args[0]]
        if part.kind == "env":
            if args[0] in scope.env:
                return scope.env[args[0]]
            if args[0] in self.base_env:
                return self.base_env[args[0]]
            if len(args) == 2:
                return args[1]
            raise self.error(f"environment variable '{args[0]}' is not set", line)
        if part.kind == "dirname":
            return str(self.path.parent)
        if part.kind == "find-pkg-share":
            try:
                return str(ament.find_package_share(args[0], self.search_path))
            except FleetError as problem:
                raise self.error(problem.message, line) from None
        raise AssertionError(part.kind)  # the reader accepts only the kinds above

    def truth(self, parts: _Parts, scope: _Scope, line: int | None, what: str) -> bool:
        value = self.resolve(parts, scope, line)
        if value.lower() in ("true", "1"):
            return True
        if value.lower() in ("false", "0"):
            return False
        raise self.error(f"{what} must be true/false/1/0, got '{value}'", line)

    # -- actions --

    def execute(self, actions: list, scope: _Scope) -> None:
        for action in actions:
            if action.condition is not None:
                keyword = action.condition.keyword
                holds = self.truth(action.condition.parts, scope, action.line, f"'{keyword}'")
                if holds != (keyword == "if"):
                    continue
            self.execute_one(action, scope)

    def execute_one(self, action: _Action, scope: _Scope) -> None:
        line = action.line
        if isinstance(action, _Arg):
            if action.name not in scope.configurations:
                if action.default is None:
                    raise self.error(
                        f"launch argument '{action.name}' is required (no default); give it as {action.name}:=VALUE",
                        line,
                    )
                scope.configurations[action.name] = self.resolve(action.default, scope, line)
            self.arguments[action.name] = scope.configurations[action.name]
        elif isinstance(action, _Let):
            name = self.resolve(action.name, scope, line)
            scope.configurations[name] = self.resolve(action.value, scope, line)
        elif isinstance(action, _SetEnv):
            scope.env[self.resolve(action.name, scope, line)] = self.resolve(action.value, scope, line)
        elif isinstance(action, _PushNamespace):
            pushed = self.resolve(action.namespace, scope, line)
            namespace = _absolute(_prefix_namespace(scope.namespace, pushed))
            if namespace is None or not _valid_namespace(namespace):  # never None: a namespace was pushed
                raise self.error(f"invalid namespace '{namespace}' (pushed '{pushed}')", line)
            scope.namespace = namespace
        elif isinstance(action, _Group):
            scoped = action.scoped
            if not isinstance(scoped, bool):
                scoped = self.truth(scoped, scope, line, "'scoped'")
            self.execute(action.actions, scope.copy() if scoped else scope)
        elif isinstance(action, _Node):
            self.drafts.append(self.node(action, scope))

    def node(self, node: _Node, scope: _Scope) -> _NodeDraft:
        line = node.line
        package = self.resolve(node.package, scope, line)
        executable = self.resolve(node.executable, scope, line)
        try:
            executable_path = ament.find_executable(package, executable, self.search_path)
        except FleetError as problem:
            raise self.error(problem.message, line) from None
        name = None if node.name is None else self.resolve(node.name, scope, line)
        if name is not None and not _NAME_TOKEN.fullmatch(name):
            raise self.error(
                f"invalid node name '{name}' (letters, digits and underscores, not starting with a digit)",
                line,
            )
        own_namespace = None if node.namespace is None else self.resolve(node.namespace, scope, line)
        namespace = _absolute(_prefix_namespace(scope.namespace, own_namespace))
        if namespace is not None and not _valid_namespace(namespace):
            raise self.error(f"invalid namespace '{namespace}' for node '{name}'", line)
        output = "log" if node.output is None else self.resolve(node.output, scope, line)
        if output not in ("screen", "log", "both"):
            raise self.error(f"'output' must be screen, log or both, got '{output}'", line)
        respawn = False if node.respawn is None else self.truth(node.respawn, scope, line, "'respawn'")
        launch = NodeLaunch(
            name=name,
            namespace=namespace,
            package=package,
            executable=executable,
            cmd=[],
            env=dict(scope.env),
            respawn=respawn,
            respawn_delay=node.respawn_delay,
            output=output,
            location=Location(self.path, line),
        )
        # launch_ros keys inline parameters by the full node name only when both name and
        # namespace are known; otherwise by the wildcard.
        key = launch.fqn if name is not None and namespace is not None else "/**"
        params: list[tuple[Any, ...]] = []
        for param in node.params:
            if isinstance(param, _ParamFile):
                file = self.resolve(param.path, scope, param.line)
                if not os.path.isfile(file):
                    raise self.error(f"parameter file '{file}' not found", param.line)
                params.append(("file", file))
            else:
                param_name = self.resolve(param.name, scope, param.line)
                value = self.param_value(param_name, param.value, scope, param.line)
                params.append(("inline", key, {param_name: value}))
        remaps = [
            (self.resolve(source, scope, line), self.resolve(target, scope, line)) for source, target in node.remaps
        ]
        return _NodeDraft(
            launch=launch,
            executable_path=executable_path,
            arguments=self.command_line(node.args, scope, line) if node.args is not None else [],
            ros_arguments=None if node.ros_args is None else self.command_line(node.ros_args, scope, line),
            params=params,
            remaps=remaps,
        )

    def param_value(self, name: str, value: Any, scope: _Scope, line: int | None) -> Any:
        """Type a parameter value like launch_ros: substituted strings are read as YAML."""
        if isinstance(value, list):
            items = [self.param_value(name, item, scope, line) for item in value]
            kinds = {type(item) for item in items}
            if len(kinds) != 1 or isinstance(items[0], list):
                raise self.error(
                    f"parameter '{name}': list items must all have one type (bool, int, float "
                    f"or string), got {items!r}",
                    line,
                )
            return items
        if not isinstance(value, tuple):
            return value  # a YAML scalar, already typed
        text = self.resolve(value, scope, line)
        if text == "":
            return ""
        try:
            typed = yaml.safe_load(text)
        except yaml.YAMLError:
            raise self.error(f"parameter '{name}': value '{text}' is not valid YAML", line) from None
        if isinstance(typed, (bool, int, float, str)):
            return typed
        if isinstance(typed, list) and typed:
            return self.param_value(name, typed, scope, line)
        raise self.error(
            f"parameter '{name}': value '{text}' is not a bool, int, float, string or list",
            line,
        )

    def command_line(self, parts: _Parts, scope: _Scope, line: int | None) -> list[str]:
        """Split like launch: literal text on (shell-quoted) whitespace; a substitution's value
        stays one piece, glued to the text it touches."""
        arguments: list[str] = []
        current: str | None = None
        for part in parts:
            if isinstance(part, _Subst):
                current = (current or "") + self.resolve_part(part, scope, line)
                continue
            try:
                tokens = shlex.split(part)
            except ValueError as problem:
                raise self.error(f"cannot split '{part}': {problem}", line) from None
            if not tokens:
                if current is not None:
                    arguments.append(current)
                current = None
                continue
            if part[0].isspace() and current is not None:
                arguments.append(current)
                current = None
            first, *rest = tokens
            current = (current or "") + first
            for token in rest:
                arguments.append(current)
                current = token
            if part[-1].isspace():
                arguments.append(current)
                current = None
        if current is not None:
            arguments.append(current)
        return arguments


# ---------------------------------------------------------------------------------------------
# Command lines


def _write_inline_params(key: str, params: dict, directory: str | None) -> str:
    with tempfile.NamedTemporaryFile("w", prefix="launch_params_", dir=directory, delete=False) as handle:
        yaml.safe_dump({key: {"ros__parameters": params}}, handle, default_flow_style=False)
        return handle.name


def _command(draft: _NodeDraft, params_dir: str | None) -> list[str]:
    """`<exe> [args] [--ros-args <ros_args>] --ros-args -r __node:= -r __ns:= --params-file ...
    -r from:=to ...`, in launch_ros's order."""
    launch = draft.launch
    cmd = [str(draft.executable_path), *draft.arguments]
    if draft.ros_arguments is not None:
        cmd += ["--ros-args", *draft.ros_arguments]
    cmd.append("--ros-args")
    if launch.name is not None:
        cmd += ["-r", f"__node:={launch.name}"]
    if launch.namespace is not None:
        cmd += ["-r", f"__ns:={launch.namespace}"]
    for param in draft.params:
        if param[0] == "file":
            cmd += ["--params-file", param[1]]
        else:
            cmd += ["--params-file", _write_inline_params(param[1], param[2], params_dir)]
    for source, target in draft.remaps:
        cmd += ["-r", f"{source}:={target}"]
    return cmd


def _process_names(nodes: list[NodeLaunch]) -> None:
    """launch names each process `<executable>-<n>`, counting per executable name."""
    counts: dict[str, int] = {}
    for node in nodes:
        base = os.path.basename(node.cmd[0])
        counts[base] = counts.get(base, 0) + 1
        node.process_name = f"{base}-{counts[base]}"


def check_launch_file(
    path: Path,
    launch_args: Mapping[str, str] | None = None,
    env: Mapping[str, str] | None = None,
    ament_search_path: str | None = None,
) -> dict[str, str]:
    """Both passes, no side effect: raise LaunchFileError for anything we cannot run; return
    the launch arguments and their values."""
    path = Path(path).absolute()
    env = dict(os.environ if env is None else env)
    if ament_search_path is None:
        ament_search_path = ament.ament_prefix_path(env)
    _, arguments = _parse(path, launch_args or {}, env, ament_search_path)
    return arguments


def load_launch_file(
    path: Path,
    launch_args: Mapping[str, str] | None = None,
    env: Mapping[str, str] | None = None,
    params_dir: str | Path | None = None,
    ament_search_path: str | None = None,
) -> LaunchPlan:
    """Read and check the whole file, then write inline parameter files (into `params_dir`,
    default the system temp directory like launch_ros) and build the command lines."""
    path = Path(path).absolute()
    env = dict(os.environ if env is None else env)
    if ament_search_path is None:
        ament_search_path = ament.ament_prefix_path(env)
    drafts, arguments = _parse(path, launch_args or {}, env, ament_search_path)
    directory = None if params_dir is None else str(params_dir)
    if directory is not None:
        os.makedirs(directory, exist_ok=True)
    nodes = []
    for draft in drafts:
        draft.launch.cmd = _command(draft, directory)
        nodes.append(draft.launch)
    _process_names(nodes)
    return LaunchPlan(path=path, arguments=arguments, nodes=nodes)


def _parse(
    path: Path, launch_args: Mapping[str, str], env: Mapping[str, str], search_path: str
) -> tuple[list[_NodeDraft], dict[str, str]]:
    if not path.name.endswith((".yaml", ".yml")):
        raise LaunchFileError(
            "the embedded runner reads YAML launch files (.launch.yaml) only; run other "
            "launch files with `ros2 launch` (--backend ros2)",
            Location(path),
        )
    from fleet.spec.yaml_source import read_input

    try:
        text = read_input(path, "launch")
    except SpecError as problem:
        raise LaunchFileError(f"cannot read launch file: {problem.message}", problem.location) from None
    for name in launch_args:
        if not _NAME_TOKEN.fullmatch(name):
            raise LaunchFileError(f"invalid launch argument name '{name}'", Location(path))
    actions = _Reader(path).read(text)
    interpreter = _Interpreter(path, launch_args, env, search_path)
    drafts = interpreter.run(actions)
    return drafts, interpreter.arguments
