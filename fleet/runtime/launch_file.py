"""Run a launch description (fleet.launchfile) like launch_ros Jazzy would, without starting
anything: the processes it starts, with launch_ros-identical command lines.

The embedded runner must start nodes exactly as `ros2 launch` would (see DESIGN.md, "How
launch_ros starts a node"; tests/conformance holds what real launch_ros started for a corpus of
files).  The reader (fleet.launchfile) has checked every action, attribute and substitution
before this runs; `_Interpreter` executes the actions in order like launch does: conditions,
launch configurations (`arg`, `let`, include arguments, and those launch_ros keeps there itself:
`ros_namespace`, `global_params`, `ros_remaps`), scoped groups, environment, includes, timers,
and drafts one `NodeLaunch` per process.  Only then are inline parameters written to temporary
files (launch_ros does the same) and the command lines assembled.
"""

from __future__ import annotations

import os
import re
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from fleet.errors import FleetError, LaunchFileError, Location, NeedsRos2Launch, did_you_mean
from fleet.launchfile import description as d
from fleet.launchfile import read_launch_file
from fleet.launchfile.substitutions import Subst, Text, parse_substitutions, split_command_line
from fleet.launchfile.substitutions import written as _written

__all__ = ["LaunchPlan", "NodeLaunch", "check_launch_file", "load_launch_file", "parse_substitutions"]
from fleet.rules import remap_problem, ros_arguments_problem, ros_name_problem
from fleet.runtime import ament

# ---------------------------------------------------------------------------------------------
# Results


@dataclass
class NodeLaunch:
    """One process (a node, or a plain `executable`), as launch would start it."""

    name: str | None  # node name given in the file; None: the executable's default
    namespace: str | None  # absolute; None when neither the node nor a group gives one
    package: str  # "" for a plain executable
    executable: str
    cmd: list[str]  # the full command line, executable path first
    env: dict[str, str] = field(default_factory=dict)  # set_env variables and the node's env in effect
    respawn: bool = False
    respawn_delay: float = 0.0
    output: str = "log"  # screen | log | both
    process_name: str = ""  # launch's process name: `<exe>-<n>`, the prefix of screen lines
    location: Location | None = None
    env_unset: tuple[str, ...] = ()  # unset_env variables in effect
    delay: float = 0.0  # seconds after the launch starts (timers)
    cwd: str | None = None

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
class LaunchArgument:
    name: str
    default: str | None  # as written, substitutions unresolved
    description: str | None
    choices: tuple[str, ...] | None


@dataclass
class LaunchPlan:
    path: Path
    arguments: dict[str, str]  # launch arguments (declared and given) and their values
    nodes: list[NodeLaunch]
    logs: list[str] = field(default_factory=list)  # what `log` actions said, in order
    params_files: list[str] = field(default_factory=list)  # the inline parameter files it wrote


# ---------------------------------------------------------------------------------------------
# Execution


@dataclass
class _Scope:
    """What a scoped group saves and restores: launch configurations (launch_ros keeps the
    pushed namespace, set_parameter and set_remap there too) and the environment."""

    configurations: dict[str, Any]
    env: dict[str, str]  # set_env variables
    unset: set[str]  # unset_env variables

    def copy(self) -> _Scope:
        # Shallow, like launch's PushLaunchConfigurations: the `global_params` and `ros_remaps`
        # lists are shared with the enclosing scope, so launch_ros's set_parameter / set_remap
        # in a scoped group also reach nodes after the group once the list exists outside it.
        # An oddity of launch_ros, kept.
        return _Scope(dict(self.configurations), dict(self.env), set(self.unset))


@dataclass
class _NodeDraft:
    """A process before its inline parameters are written: params are ('file', path),
    ('inline', key, {name: value}, where written) or ('rule', 'name:=value')."""

    launch: NodeLaunch
    executable_path: Path | None  # None: a plain executable (cmd is final)
    arguments: list[str]
    ros_arguments: list[str] | None
    params: list[tuple]
    remaps: list[tuple[str, str]]
    order: int = 0
    process_base: str = ""


@dataclass
class _Timer:
    due: float
    order: int
    actions: list[d.Action]
    file: Path


# What render cannot know of the computer that will run the file (see _Interpreter.bundle).
_UNKNOWN = "\x00unknown\x00"
# A bundle's directory and the names of its files.
Bundle = tuple[Path, frozenset[str]]

_SUBSTITUTION_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _prefix_namespace(base: str | None, namespace: str | None) -> str | None:
    """launch_ros's prefix_namespace: a relative namespace is appended to the base, an absolute
    one replaces it, an empty base is no base; trailing slashes go."""
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
    return tokens[0] == "" and not any(ros_name_problem(token) for token in tokens[1:])


def _condition_value(value: str) -> bool | None:
    lowered = value.lower()
    if lowered in ("true", "1"):
        return True
    if lowered in ("false", "0"):
        return False
    return None


class _Interpreter:
    """Run the actions like launch does and draft the processes."""

    def __init__(
        self,
        launch_args: Mapping[str, str],
        env: Mapping[str, str],
        search_path: str,
        bundle: Bundle | None = None,
    ):
        # With a bundle, the file is checked away from the computer that will run it (render):
        # what only that computer can tell (packages, executables, environment, files outside the
        # bundle, included files) is _UNKNOWN, and no check is made of what depends on it.
        self.bundle = bundle
        self.unknown_configurations = False  # a skipped include or branch may have set any
        self.base_env = env
        self.search_path = search_path
        self.launch_args = dict(launch_args)
        self.arguments: dict[str, str] = {}
        self.declared: dict[str, LaunchArgument] = {}
        self.drafts: list[_NodeDraft] = []
        self.logs: list[str] = []
        self.timers: list[_Timer] = []
        self.now = 0.0
        self.sequence = 0
        self.including: list[Path] = []
        self.read_cache: dict[Path, d.LaunchDescription] = {}  # a file included twice is read once

    def run(self, description: d.LaunchDescription) -> list[_NodeDraft]:
        # `ros2 launch FILE a:=b` includes FILE with those arguments: they become launch
        # configurations (also the undeclared ones), set before the file runs.
        scope = _Scope(dict(self.launch_args), {}, set())
        self.arguments.update(self.launch_args)
        self.include(description, scope, top=True)
        # Timers fire after everything else has run, in the configurations and environment of
        # the top of the launch at that time: a timer in a scoped group has lost the group's
        # namespace and `let`s when it fires (launch keeps only its locals).  Kept, as in launch.
        while self.timers:
            self.timers.sort(key=lambda timer: (timer.due, timer.order))
            timer = self.timers.pop(0)
            self.now = timer.due
            self.execute(timer.actions, scope, timer.file)
        _check_unique_names(self.drafts)
        return self.drafts

    def include(self, description: d.LaunchDescription, scope: _Scope, top: bool = False) -> None:
        path = description.path
        self.including.append(path)
        try:
            self.execute(description.actions, scope, path, top)
        finally:
            self.including.pop()

    # -- substitutions --

    def resolve(self, parts: Text, scope: _Scope, where: Location, file: Path) -> str:
        return "".join(self.resolve_part(part, scope, where, file) for part in parts)

    def resolve_part(self, part: str | Subst, scope: _Scope, where: Location, file: Path) -> str:
        if isinstance(part, str):
            return part
        args = [self.resolve(arg, scope, where, file) for arg in part.args]
        kind = part.kind
        if kind == "var":
            if args[0] not in scope.configurations or not isinstance(scope.configurations[args[0]], str):
                if self.unknown_configurations:
                    return _UNKNOWN
                defined = (name for name, value in scope.configurations.items() if isinstance(value, str))
                hint = did_you_mean(args[0], defined)
                raise LaunchFileError(f"launch configuration '{args[0]}' is not defined{hint}", where)
            return scope.configurations[args[0]]
        if kind == "env":
            if args[0] in scope.env:
                return scope.env[args[0]]
            if args[0] in self.base_env and args[0] not in scope.unset:
                return self.base_env[args[0]]
            if self.bundle is not None and args[0] not in scope.unset:
                return _UNKNOWN  # the agent's environment decides, not the default (checked first)
            if len(args) == 2:
                return args[1]
            raise LaunchFileError(f"environment variable '{args[0]}' is not set", where)
        if kind == "dirname":
            return str(file.parent)
        if kind == "filename":
            return str(file)
        if kind in ("find-pkg-share", "find-pkg-prefix", "exec-in-pkg"):
            if self.bundle is not None:
                return _UNKNOWN
            try:
                if kind == "find-pkg-share":
                    return str(ament.find_package_share(args[0], self.search_path))
                if kind == "find-pkg-prefix":
                    return str(ament.find_package_prefix(args[0], self.search_path))
                return str(ament.find_executable(args[1], args[0], self.search_path))
            except FleetError as problem:
                raise LaunchFileError(problem.message, where) from None
        if kind in ("not", "and", "or"):
            values = [self.truth_of(arg, where, f"'$({kind})'") for arg in args]
            result = not values[0] if kind == "not" else all(values) if kind == "and" else any(values)
            return "true" if result else "false"
        if kind in ("equals", "not-equals"):
            same = _equal(args[0], args[1] if len(args) == 2 else "")
            return "true" if same == (kind == "equals") else "false"
        raise AssertionError(kind)  # the reader accepts only the kinds above

    def truth_of(self, value: str, where: Location, what: str) -> bool:
        if _UNKNOWN in value:
            return True  # see execute: the caller skips what an unknown condition guards
        result = _condition_value(value)
        if result is None:
            raise LaunchFileError(f"{what} must be true/false/1/0, got '{value}'", where)
        return result

    def truth(self, parts: Text, scope: _Scope, where: Location, file: Path, what: str) -> bool:
        return self.truth_of(self.resolve(parts, scope, where, file), where, what)

    # -- actions --

    def execute(self, actions: list[d.Action], scope: _Scope, file: Path, top: bool = False) -> None:
        for action in actions:
            if action.condition is not None:
                keyword = action.condition.keyword
                value = self.resolve(action.condition.text, scope, action.where, file)
                if _UNKNOWN in value:
                    self.unknown_configurations = True  # whether it runs is not known here
                    continue
                holds = self.truth_of(value, action.where, f"'{keyword}'")
                if holds != (keyword == "if"):
                    continue
            self.execute_one(action, scope, file, top)

    def execute_one(self, action: d.Action, scope: _Scope, file: Path, top: bool) -> None:
        where = action.where

        def text(parts: Text) -> str:
            return self.resolve(parts, scope, where, file)

        if isinstance(action, d.DeclareArgument):
            self.declare(action, scope, file, top)
        elif isinstance(action, d.SetConfiguration):
            scope.configurations[text(action.name)] = text(action.value)
        elif isinstance(action, d.SetEnv):
            name = text(action.name)
            scope.env[name] = text(action.value)
            scope.unset.discard(name)
        elif isinstance(action, d.UnsetEnv):
            name = text(action.name)
            scope.env.pop(name, None)
            scope.unset.add(name)
        elif isinstance(action, d.PushNamespace):
            pushed = text(action.namespace)
            previous = scope.configurations.get("ros_namespace")
            previous = previous if isinstance(previous, str) else None
            namespace = _absolute(_prefix_namespace(previous, pushed))
            if namespace is None or (_UNKNOWN not in namespace and not _valid_namespace(namespace)):
                raise LaunchFileError(f"invalid namespace '{namespace}' (pushed '{pushed}')", where)
            scope.configurations["ros_namespace"] = namespace
        elif isinstance(action, d.Group):
            # A string `scoped` is taken for its truth as Python would (see the reader).
            scoped = action.scoped if isinstance(action.scoped, bool) else bool(text(action.scoped))
            inner = scope.copy() if scoped else scope
            for kept, value in action.keep:
                inner.configurations[text(kept)] = text(value)
            self.execute(action.actions, inner, file)
        elif isinstance(action, d.Include):
            self.include_file(action, scope, file)
        elif isinstance(action, d.Timer):
            if isinstance(action.period, float):
                period = action.period
            else:
                written_period = text(action.period)
                if _UNKNOWN in written_period:
                    written_period = "0"
                try:
                    period = float(written_period)
                except ValueError:
                    raise LaunchFileError(f"timer 'period' must be a number, got '{written_period}'", where) from None
            self.sequence += 1
            self.timers.append(_Timer(self.now + period, self.sequence, action.actions, file))
        elif isinstance(action, d.Log):
            self.logs.append(text(action.message))
        elif isinstance(action, d.SetParameter):
            name = text(action.name)
            value = self.param_value(name, action.value, scope, where, file, typed=True)
            # The list is changed in place: see _Scope.copy.
            scope.configurations.setdefault("global_params", []).append((name, value))
        elif isinstance(action, d.SetRemap):
            remap = _checked_remap(text(action.source), text(action.target), where)
            scope.configurations.setdefault("ros_remaps", []).append(remap)
        elif isinstance(action, d.Node):
            self.drafts.append(self.node(action, scope, file))
        elif isinstance(action, d.Executable):
            self.drafts.append(self.executable(action, scope, file))
        else:
            raise AssertionError(action)

    def declare(self, action: d.DeclareArgument, scope: _Scope, file: Path, top: bool) -> None:
        if top:
            default = None if action.default is None else _written(action.default)
            self.declared.setdefault(
                action.name, LaunchArgument(action.name, default, action.description, action.choices)
            )
        if action.name not in scope.configurations:
            if action.default is None:
                raise LaunchFileError(
                    f"launch argument '{action.name}' is required (no default); give it as {action.name}:=VALUE",
                    action.where,
                )
            scope.configurations[action.name] = self.resolve(action.default, scope, action.where, file)
        value = scope.configurations[action.name]
        if action.choices is not None and value not in action.choices and _UNKNOWN not in value:
            raise LaunchFileError(
                f"argument '{action.name}' is '{value}', not one of its choices ({', '.join(action.choices)})",
                action.where,
            )
        if top:
            self.arguments[action.name] = value

    def include_file(self, action: d.Include, scope: _Scope, file: Path) -> None:
        where = action.where
        written_target = self.resolve(action.file, scope, where, file)
        if self.bundle is not None:
            # The included file is not in the bundle: the agent's computer has it, or not.
            self.bundle_file_check(written_target, where, "included launch file")
            for name, value in action.arguments:
                scope.configurations[self.resolve(name, scope, where, file)] = self.resolve(value, scope, where, file)
            self.unknown_configurations = True
            return
        target = Path(written_target)
        if not target.is_absolute():
            target = Path.cwd() / target
        if target in self.including:
            chain = " -> ".join(path.name for path in [*self.including, target])
            raise LaunchFileError(f"include cycle: {chain}", where)
        if not target.is_file():
            raise LaunchFileError(f"included launch file '{target}' not found", where)
        included = self.read_cache.get(target)
        if included is None:
            try:
                included = self.read_cache[target] = read_launch_file(target)
            except LaunchFileError as problem:
                if "Python launch file" in problem.message:  # said where the include is
                    raise NeedsRos2Launch(problem.message, where) from None
                raise
        given = []
        for name, value in action.arguments:
            given.append(self.resolve(name, scope, where, file))
            # Include arguments are set in the including scope (launch does not scope an
            # include): they stay defined after it.
            scope.configurations[given[-1]] = self.resolve(value, scope, where, file)
        for argument in _required_arguments(included.actions):
            if argument.name not in given:
                raise LaunchFileError(
                    f"included file {target.name} needs argument '{argument.name}' (give it with arg: name/value)",
                    where,
                )
        self.include(included, scope)

    def process_env(self, env: list[tuple[Text, Text]], scope: _Scope, where: Location, file: Path) -> dict[str, str]:
        result = dict(scope.env)
        for name, value in env:
            result[self.resolve(name, scope, where, file)] = self.resolve(value, scope, where, file)
        return result

    def process_common(self, action: d.Process, scope: _Scope, file: Path) -> dict[str, Any]:
        where = action.where
        output = "log" if action.output is None else self.resolve(action.output, scope, where, file)
        if _UNKNOWN in output:
            output = "log"
        if output not in ("screen", "log", "both"):
            raise LaunchFileError(f"'output' must be screen, log or both, got '{output}'", where)
        respawn = False if action.respawn is None else self.truth(action.respawn, scope, where, file, "'respawn'")
        env = self.process_env(action.env, scope, where, file)
        unset = tuple(sorted(name for name in scope.unset if name not in env))
        return {
            "env": env,
            "env_unset": unset,
            "respawn": respawn,
            "respawn_delay": action.respawn_delay,
            "output": output,
            "location": where,
            "delay": self.now,
        }

    def executable(self, action: d.Executable, scope: _Scope, file: Path) -> _NodeDraft:
        where = action.where
        cmd = self.command_line(action.cmd, scope, where, file)
        if not cmd:
            raise LaunchFileError("'cmd' of 'executable' is empty", where)
        name = None if action.name is None else self.resolve(action.name, scope, where, file)
        cwd = None if action.cwd is None else self.resolve(action.cwd, scope, where, file)
        launch = NodeLaunch(
            name=None,
            namespace=None,
            package="",
            executable=os.path.basename(cmd[0]),
            cmd=cmd,
            cwd=cwd,
            **self.process_common(action, scope, file),
        )
        self.sequence += 1
        return _NodeDraft(launch, None, [], None, [], [], self.sequence, name or os.path.basename(cmd[0]))

    def node(self, node: d.Node, scope: _Scope, file: Path) -> _NodeDraft:
        where = node.where

        def text(parts: Text) -> str:
            return self.resolve(parts, scope, where, file)

        package = text(node.package)
        executable = text(node.executable)
        try:
            if self.bundle is not None:  # looked up on the agent's computer
                executable_path = Path(executable)
            else:
                executable_path = ament.find_executable(package, executable, self.search_path)
        except FleetError as problem:
            raise LaunchFileError(problem.message, where) from None
        name = None if node.name is None else text(node.name)
        if name is not None and _UNKNOWN not in name and (name_problem := ros_name_problem(name)):
            raise LaunchFileError(f"node {name_problem}", where)
        own_namespace = None if node.namespace is None else text(node.namespace)
        base = scope.configurations.get("ros_namespace")
        namespace = _absolute(_prefix_namespace(base if isinstance(base, str) else None, own_namespace))
        if namespace is not None and _UNKNOWN not in namespace and not _valid_namespace(namespace):
            raise LaunchFileError(f"invalid namespace '{namespace}' for node '{name}'", where)
        launch = NodeLaunch(
            name=name,
            namespace=namespace,
            package=package,
            executable=executable,
            cmd=[],
            **self.process_common(node, scope, file),
        )
        # launch_ros keys inline parameters by the full node name only when both name and
        # namespace are known; otherwise by the wildcard.
        key = launch.fqn if name is not None and namespace is not None else "/**"
        params: list[tuple[Any, ...]] = []
        # set_parameter's parameters come first, as `-p name:=value` rules.
        for param_name, value in scope.configurations.get("global_params", []):
            params.append(("rule", f"{param_name}:={_rule_value(value)}"))
        for param in node.params:
            if isinstance(param, d.ParamFile):
                path = self.resolve(param.path, scope, param.where, file)
                if self.bundle is not None:
                    self.bundle_file_check(path, param.where, "parameter file")
                elif not os.path.isfile(path):
                    raise LaunchFileError(f"parameter file '{path}' not found", param.where)
                params.append(("file", os.path.abspath(path)))
            else:
                params.append(("inline", key, self.inline_param(param, scope, file), param.where))
        remaps = list(scope.configurations.get("ros_remaps", []))
        remaps += [_checked_remap(text(source), text(target), where) for source, target in node.remaps]
        exec_name = None if node.exec_name is None else text(node.exec_name)
        arguments = self.command_line(node.args, scope, where, file) if node.args is not None else []
        ros_arguments = None if node.ros_args is None else self.command_line(node.ros_args, scope, where, file)
        # launch_ros puts ros_args after a --ros-args of its own; args may hold ROS arguments too.
        given = [*arguments, "--", "--ros-args", *(ros_arguments or [])]
        if _UNKNOWN not in "".join(given) and (ros_problem := ros_arguments_problem(given)):
            raise LaunchFileError(f"node {name or executable}: {ros_problem}", where)
        self.sequence += 1
        return _NodeDraft(
            launch=launch,
            executable_path=executable_path,
            arguments=arguments,
            ros_arguments=ros_arguments,
            params=params,
            remaps=remaps,
            order=self.sequence,
            process_base=exec_name or executable_path.name,
        )

    def bundle_file_check(self, path: str, where: Location, what: str) -> None:
        """A file the unit's own directory would have to hold must be in the bundle; any other
        is the agent computer's to have."""
        assert self.bundle is not None
        directory, names = self.bundle
        if _UNKNOWN not in path and Path(path).parent == directory and Path(path).name not in names:
            raise LaunchFileError(f"{what} '{path}' not found", where)

    def inline_param(self, param: d.InlineParam, scope: _Scope, file: Path) -> dict[str, Any]:
        name = self.resolve(param.name, scope, param.where, file)
        if param.nested:
            result: dict[str, Any] = {}
            for child in param.value:
                for child_name, value in self.inline_param(child, scope, file).items():
                    result[f"{name}.{child_name}"] = value  # launch_ros flattens nested parameters
            return result
        return {name: self.param_value(name, param.value, scope, param.where, file)}

    def param_value(
        self, name: str, value: Any, scope: _Scope, where: Location, file: Path, typed: bool = False
    ) -> Any:
        """Type a parameter value like launch_ros: text holding a substitution is read as YAML
        once substituted; text without one stays a string (`value: 'true'` is the string
        "true" to launch_ros, not a bool); YAML scalars keep the type the file gave them."""
        if isinstance(value, list):
            items = [self.param_value(name, item, scope, where, file) for item in value]
            kinds = {type(item) for item in items}
            if len(kinds) != 1 or isinstance(items[0], list):
                raise LaunchFileError(
                    f"parameter '{name}': list items must all have one type (bool, int, float or string), "
                    f"got {items!r}",
                    where,
                )
            return items
        if not isinstance(value, tuple):
            return value  # a YAML scalar, already typed
        text = self.resolve(value, scope, where, file)
        if _UNKNOWN in text:  # kept as written, so that render can show it (InlineSetting.shown)
            return _UNKNOWN + _written(value)
        if not typed and all(isinstance(part, str) for part in value):
            return text
        if text == "":
            return ""
        try:
            typed = yaml.safe_load(text)
        except yaml.YAMLError:
            raise LaunchFileError(f"parameter '{name}': value '{text}' is not valid YAML", where) from None
        if isinstance(typed, (bool, int, float, str)):
            return typed
        if isinstance(typed, list) and typed:
            return self.param_value(name, typed, scope, where, file)
        raise LaunchFileError(f"parameter '{name}': value '{text}' is not a bool, int, float, string or list", where)

    def command_line(self, parts: Text, scope: _Scope, where: Location, file: Path) -> list[str]:
        """The arguments as launch passes them (split_command_line), substitutions resolved."""
        try:
            arguments = split_command_line(parts)
        except ValueError as problem:
            raise LaunchFileError(f"cannot split '{_written(parts)}': {problem}", where) from None
        return [self.resolve(argument, scope, where, file) for argument in arguments]


def _checked_remap(source: str, target: str, where: Location) -> tuple[str, str]:
    """The remap, if rcl can parse `-r source:=target` (else the node would not start)."""
    if _UNKNOWN not in source + target and (problem := remap_problem(source, target)):
        raise LaunchFileError(f"invalid remap {source!r} -> {target!r}: {problem}", where)
    return source, target


def _check_unique_names(drafts: list[_NodeDraft]) -> None:
    """Two nodes of one full name are one name twice to ROS (each hides the other's topics,
    services and parameters): refused at the second."""
    seen: dict[str, Location | None] = {}
    for draft in sorted(drafts, key=lambda draft: (draft.launch.delay, draft.order)):
        fqn = draft.launch.fqn
        if fqn is None or _UNKNOWN in fqn:
            continue
        if fqn in seen:
            first = seen[fqn]
            at = f" (the first at {first.line}:{first.column})" if first and first.line else ""
            raise LaunchFileError(
                f"two nodes are named {fqn}{at}: ROS needs each node's full name once", draft.launch.location
            )
        seen[fqn] = draft.launch.location


def _equal(left: str, right: str) -> bool:
    """launch's EqualsSubstitution: compared as bools, then numbers, then text."""
    left_truth, right_truth = _condition_value(left), _condition_value(right)
    if left_truth is not None and right_truth is not None:
        return left_truth == right_truth
    try:
        return float(left) == float(right)
    except ValueError:
        return left == right


def _rule_value(value: Any) -> str:
    # launch_ros writes `-p name:=<value>` with the Python value as text.
    return str(value)


def _required_arguments(actions: list[d.Action]) -> list[d.DeclareArgument]:
    """The arguments an include must give: declared without default and not under a condition
    (launch's best-effort check looks into groups, not into timers or includes)."""
    found = []
    for action in actions:
        if action.condition is not None:
            continue
        if isinstance(action, d.DeclareArgument) and action.default is None:
            found.append(action)
        elif isinstance(action, d.Group):
            found += _required_arguments(action.actions)
    return found


# ---------------------------------------------------------------------------------------------
# Command lines


def _write_inline_params(key: str, params: dict, directory: str | None) -> str:
    with tempfile.NamedTemporaryFile("w", prefix="launch_params_", dir=directory, delete=False) as handle:
        yaml.safe_dump({key: {"ros__parameters": params}}, handle, default_flow_style=False, allow_unicode=True)
        return handle.name


def _command(draft: _NodeDraft, params_dir: str | None, written: list[str]) -> list[str]:
    """`<exe> [args] [--ros-args <ros_args>] --ros-args -r __node:= -r __ns:= -p ... --params-file ...
    -r from:=to ...`, in launch_ros's order; the inline parameter files it writes are added to `written`."""
    launch = draft.launch
    if draft.executable_path is None:
        return list(launch.cmd)
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
        elif param[0] == "rule":
            cmd += ["-p", param[1]]
        else:
            written.append(_write_inline_params(param[1], param[2], params_dir))
            cmd += ["--params-file", written[-1]]
    for source, target in draft.remaps:
        cmd += ["-r", f"{source}:={target}"]
    return cmd


def _process_names(drafts: list[_NodeDraft]) -> list[NodeLaunch]:
    """launch names each process `<executable>-<n>` with ONE counter for the whole launch,
    counting in the order processes start (timers last); the processes in that order."""
    ordered = sorted(drafts, key=lambda draft: (draft.launch.delay, draft.order))
    for number, draft in enumerate(ordered, start=1):
        draft.launch.process_name = f"{draft.process_base}-{number}"
    return [draft.launch for draft in ordered]


def _interpret(
    path: Path, launch_args: Mapping[str, str], env: Mapping[str, str] | None, search_path: str | None
) -> _Interpreter:
    environment = dict(os.environ if env is None else env)
    if search_path is None:
        search_path = ament.ament_prefix_path(environment)
    for name in launch_args:
        if not _SUBSTITUTION_NAME.fullmatch(name):
            raise LaunchFileError(f"invalid launch argument name '{name}'", Location(path))
    description = read_launch_file(path)
    interpreter = _Interpreter(launch_args, environment, search_path)
    interpreter.run(description)
    return interpreter


@dataclass(frozen=True)
class InlineSetting:
    """A parameter value a launch file gives a node inline (`param: [{name, value}]`)."""

    value: Any
    where: Location

    @property
    def known(self) -> bool:
        """False when check_bundle_launch cannot tell the value: it depends on what only the
        computer that runs the file can tell (`$(env ...)`, `$(find-pkg-share ...)`)."""
        items = self.value if isinstance(self.value, list) else [self.value]
        return not any(isinstance(item, str) and _UNKNOWN in item for item in items)

    @property
    def shown(self) -> Any:
        """The value for people to read: one only the agent's computer can tell as the launch
        file writes it (`$(env ROUTE)`), not as the marker it holds here."""
        if isinstance(self.value, list):
            return [_without_marker(item) for item in self.value]
        return _without_marker(self.value)


def _without_marker(value: Any) -> Any:
    return value.replace(_UNKNOWN, "") if isinstance(value, str) else value


def check_bundle_launch(
    description: d.LaunchDescription, files: frozenset[str], params_files: frozenset[str] = frozenset()
) -> tuple[dict[str, dict[str, InlineSetting]], dict[str, Location | None]]:
    """Run a unit's launch file (read from its bundle, before any agent has it) the way
    check_launch_file would on an agent, less what only the agent's computer can tell: whether
    packages, executables, environment variables, included files and files outside the bundle are
    there.  Raises LaunchFileError, located in `description.path`.

    Returns, for each node (by name), the parameters it is given inline that the robot's
    parameter file cannot change: those after one of the bundle's `params_files` (later parameter
    files win), or all of them for a node started without any; and each node (by name) it starts
    without any of them, with where it starts it: none of the files' values reach such a node (its
    process reads only the files it is given)."""
    directory = description.path.parent
    interpreter = _Interpreter({}, {}, "", bundle=(directory, files))
    interpreter.run(description)
    inline_wins: dict[str, dict[str, InlineSetting]] = {}
    without_file: dict[str, Location | None] = {}
    if not params_files:
        return inline_wins, without_file
    paths = {os.path.abspath(directory / name) for name in params_files}
    for draft in interpreter.drafts:
        if draft.launch.name is None:  # a plain executable, or a node no parameter file section can name
            continue
        read_file = False
        given: dict[str, InlineSetting] = {}  # inline since the last of the files, or since the start
        for param in draft.params:
            if param[0] == "file" and param[1] in paths:
                read_file = True
                given = {}
            elif param[0] == "inline":
                given.update({name: InlineSetting(value, param[3]) for name, value in param[2].items()})
        if given:
            inline_wins.setdefault(draft.launch.name, {}).update(given)
        if not read_file:
            without_file[draft.launch.name] = draft.launch.location
    return inline_wins, without_file


def check_launch_file(
    path: Path,
    launch_args: Mapping[str, str] | None = None,
    env: Mapping[str, str] | None = None,
    ament_search_path: str | None = None,
) -> dict[str, str]:
    """Read and run the file without side effects: raise LaunchFileError for anything we cannot
    run; return the launch arguments and their values."""
    return _interpret(Path(path).absolute(), launch_args or {}, env, ament_search_path).arguments


def declared_arguments(path: Path) -> list[LaunchArgument]:
    """The launch arguments the file declares at its top (as `ros2 launch --show-args`)."""
    description = read_launch_file(Path(path).absolute())
    found: dict[str, LaunchArgument] = {}
    for action in description.actions:
        if isinstance(action, d.DeclareArgument) and action.name not in found:
            default = None if action.default is None else _written(action.default)
            found[action.name] = LaunchArgument(action.name, default, action.description, action.choices)
    return list(found.values())


def load_launch_file(
    path: Path,
    launch_args: Mapping[str, str] | None = None,
    env: Mapping[str, str] | None = None,
    params_dir: str | Path | None = None,
    ament_search_path: str | None = None,
) -> LaunchPlan:
    """Read and run the whole file, then write inline parameter files (into `params_dir`,
    default the system temp directory like launch_ros) and build the command lines."""
    path = Path(path).absolute()
    interpreter = _interpret(path, launch_args or {}, env, ament_search_path)
    directory = None if params_dir is None else str(params_dir)
    if directory is not None:
        os.makedirs(directory, exist_ok=True)
    written: list[str] = []
    for draft in interpreter.drafts:
        draft.launch.cmd = _command(draft, directory, written)
    nodes = _process_names(interpreter.drafts)
    return LaunchPlan(
        path=path, arguments=interpreter.arguments, nodes=nodes, logs=interpreter.logs, params_files=written
    )
