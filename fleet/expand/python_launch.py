"""Emit a Python launch file equivalent to a rendered YAML launch description.

For teams that use Python launch files: the same actions as GroupAction + PushRosNamespace +
Node, as the ROS 2 launch tutorials write them.  Every string from the description is emitted
with repr(), so it is a Python literal and never code.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from fleet.errors import Location, TemplateError
from fleet.launchfile.substitutions import Subst, Text, parse_substitutions, split_command_line

_HEADER = """\
{comment}
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, GroupAction, SetEnvironmentVariable, SetLaunchConfiguration
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import EnvironmentVariable, LaunchConfiguration, ThisLaunchFileDir
from launch_ros.actions import Node, PushRosNamespace
from launch_ros.substitutions import FindPackageShare
{extra}

def generate_launch_description():
    return LaunchDescription(
"""


def python_source(launch: dict[str, Any], comment: str, template_file: str | Path) -> str:
    """python_launch_source, a description it cannot express refused as the template's error."""
    try:
        return python_launch_source(launch, comment)
    except ValueError as problem:
        raise TemplateError(f"cannot write the Python launch file: {problem}", Location(template_file)) from None


def python_launch_source(launch: dict[str, Any], comment: str) -> str:
    """Python source of a launch file doing what the YAML `launch` document does."""
    comment_lines = "\n".join(f"# {line}".rstrip() for line in comment.splitlines())
    body = _actions(launch["launch"], indent=8)
    # Imports of the actions the tutorials add, only when used: the common files stay as they were.
    extra = "".join(line + "\n" for name, line in _EXTRA_IMPORTS.items() if re.search(rf"\b{name}\(", body))
    return _HEADER.format(comment=comment_lines, extra=extra) + body + "\n    )\n"


_EXTRA_IMPORTS = {
    "ThisLaunchFile": "from launch.substitutions import ThisLaunchFile",
    "FindPackagePrefix": "from launch_ros.substitutions import FindPackagePrefix",
    "ExecutableInPackage": "from launch_ros.substitutions import ExecutableInPackage",
    "NotSubstitution": "from launch.substitutions import NotSubstitution",
    "AndSubstitution": "from launch.substitutions import AndSubstitution",
    "OrSubstitution": "from launch.substitutions import OrSubstitution",
    "EqualsSubstitution": "from launch.substitutions import EqualsSubstitution",
    "NotEqualsSubstitution": "from launch.substitutions import NotEqualsSubstitution",
    "TimerAction": "from launch.actions import TimerAction",
    "IncludeLaunchDescription": "from launch.actions import IncludeLaunchDescription",
    "AnyLaunchDescriptionSource": "from launch.launch_description_sources import AnyLaunchDescriptionSource",
    "ExecuteProcess": "from launch.actions import ExecuteProcess",
    "LogInfo": "from launch.actions import LogInfo",
    "UnsetEnvironmentVariable": "from launch.actions import UnsetEnvironmentVariable",
    "SetParameter": "from launch_ros.actions import SetParameter",
    "SetRemap": "from launch_ros.actions import SetRemap",
}


def _actions(actions: list[Any], indent: int) -> str:
    pad = " " * indent
    items = [_action(action, indent + 4) for action in actions]
    inner = "".join(f"{' ' * (indent + 4)}{item},\n" for item in items)
    return f"{pad}[\n{inner}{pad}]"


def _action(action: dict[str, Any], indent: int) -> str:
    ((kind, body),) = action.items()
    if kind == "group":
        children = body if isinstance(body, list) else body.get("children", [])
        options = {} if isinstance(body, list) else body
        kwargs = _condition(options)
        scoped = options.get("scoped", True)
        return (
            f"GroupAction(\n{_actions(children, indent + 4)},\n{' ' * (indent + 4)}scoped={bool(scoped)!r}"
            f"{kwargs},\n{' ' * indent})"
        )
    if kind == "push_ros_namespace":
        return f"PushRosNamespace({_expr(body['namespace'])}{_condition(body)})"
    if kind == "arg":
        parts = [repr(str(body["name"]))]
        if "default" in body:
            parts.append(f"default_value={_expr(body['default'])}")
        if "description" in body:
            parts.append(f"description={str(body['description'])!r}")
        if body.get("choice"):
            parts.append(f"choices={[str(item['value']) for item in body['choice']]!r}")
        return f"DeclareLaunchArgument({', '.join(parts)}{_condition(body)})"
    if kind == "let":
        return f"SetLaunchConfiguration({str(body['name'])!r}, {_expr(body['value'])}{_condition(body)})"
    if kind == "set_env":
        return f"SetEnvironmentVariable({str(body['name'])!r}, {_expr(body['value'])}{_condition(body)})"
    if kind == "node":
        return _node(body, indent)
    if kind == "unset_env":
        return f"UnsetEnvironmentVariable({_expr(body['name'])}{_condition(body)})"
    if kind == "log":
        return f"LogInfo(msg={_expr(body['message'])}{_condition(body)})"
    if kind == "set_parameter":
        return f"SetParameter(name={_expr(body['name'])}, value={_expr(body['value'])}{_condition(body)})"
    if kind == "set_remap":
        return f"SetRemap(src={_expr(body['from'])}, dst={_expr(body['to'])}{_condition(body)})"
    if kind == "timer":
        children = body.get("children", [])
        return (
            f"TimerAction(\n{' ' * (indent + 4)}period={_expr(body['period'])},\n{' ' * (indent + 4)}actions="
            f"{_actions(children, indent + 4).lstrip()}{_condition(body)},\n{' ' * indent})"
        )
    if kind == "include":
        pairs = ", ".join(f"({_expr(item['name'])}, {_expr(item['value'])})" for item in body.get("arg", []))
        return (
            f"IncludeLaunchDescription(AnyLaunchDescriptionSource({_expr(body['file'])}), "
            f"launch_arguments=[{pairs}]{_condition(body)})"
        )
    if kind == "executable":
        parts = [f"cmd={_token_list(body['cmd'])}"]
        if "name" in body:
            parts.append(f"name={_expr(body['name'])}")
        if "output" in body:
            parts.append(f"output={str(body['output'])!r}")
        if body.get("env"):
            parts.append(f"additional_env={_env(body['env'])}")
        return f"ExecuteProcess({', '.join(parts)}{_condition(body)})"
    raise ValueError(f"no Python equivalent emitted for launch action {kind!r}")


def _node(body: dict[str, Any], indent: int) -> str:
    pad = " " * (indent + 4)
    lines = [f"package={_expr(body['pkg'])}", f"executable={_expr(body['exec'])}"]
    if "name" in body:
        lines.append(f"name={_expr(body['name'])}")
    if "namespace" in body:
        lines.append(f"namespace={_expr(body['namespace'])}")
    if "output" in body:
        lines.append(f"output={str(body['output'])!r}")
    if "args" in body:
        lines.append(f"arguments={_token_list(body['args'])}")
    if "ros_args" in body:
        lines.append(f"ros_arguments={_token_list(body['ros_args'])}")
    parameters = _parameters(body.get("param", []))
    if parameters:
        lines.append(f"parameters=[{', '.join(parameters)}]")
    if body.get("remap"):
        pairs = ", ".join(f"({_expr(item['from'])}, {_expr(item['to'])})" for item in body["remap"])
        lines.append(f"remappings=[{pairs}]")
    if "respawn" in body:
        lines.append(f"respawn={_boolean(body['respawn'])}")
    if "respawn_delay" in body:
        lines.append(f"respawn_delay={float(body['respawn_delay'])!r}")
    if body.get("env"):
        lines.append(f"additional_env={_env(body['env'])}")
    condition = _condition(body).removeprefix(", ")
    if condition:
        lines.append(condition)
    inner = "".join(f"{pad}{line},\n" for line in lines)
    return f"Node(\n{inner}{' ' * indent})"


def _env(items: list[dict[str, Any]]) -> str:
    return "{" + ", ".join(f"{str(item['name'])!r}: {_expr(item['value'])}" for item in items) + "}"


def _parameters(items: list[dict[str, Any]]) -> list[str]:
    """Files in order, then all inline name/value pairs as one dict: what launch_ros's YAML
    frontend builds from `param:` entries, so both files produce the same command line."""
    files = [_expr(item["from"]) for item in items if "from" in item]
    inline = [f"{str(item['name'])!r}: {_expr(item['value'])}" for item in items if "from" not in item]
    if inline:
        files.append("{" + ", ".join(inline) + "}")
    return files


def _condition(body: Any) -> str:
    if not isinstance(body, dict):
        return ""
    if "if" in body:
        return f", condition=IfCondition({_expr(body['if'])})"
    if "unless" in body:
        return f", condition=UnlessCondition({_expr(body['unless'])})"
    return ""


def _boolean(value: Any) -> str:
    """YAML launch files spell booleans 'true'/'false'; Python launch wants True/False there
    (or a substitution, which is passed through)."""
    if isinstance(value, bool):
        return repr(value)
    if str(value).lower() in ("true", "false"):
        return repr(str(value).lower() == "true")
    return _expr(value)


def _token_list(text: Any) -> str:
    """An argument string as the list of arguments the embedded runner passes for it: one
    splitter (split_command_line), so quotes mean the same in both files."""
    return "[" + ", ".join(_text_expr(argument) for argument in split_arguments(str(text))) + "]"


def split_arguments(text: str) -> tuple[Text, ...]:
    """The arguments of `args`/`ros_args`/`cmd` text, as launch's frontend splits them."""
    return split_command_line(parse_substitutions(text))


def _expr(value: Any) -> str:
    """A launch value as a Python expression: a literal, or a list of substitutions."""
    if isinstance(value, bool):
        return repr(value)
    if isinstance(value, (int, float)):
        return repr(str(value))
    return _text_expr(parse_substitutions(str(value)))


def _text_expr(text: Text) -> str:
    parts = [repr(part) if isinstance(part, str) else _substitution(part) for part in text]
    if len(text) == 1 and isinstance(text[0], str):
        return parts[0]
    return "[" + ", ".join(parts) + "]" if parts else "''"


# Substitution -> (Python class, number of arguments it is given).
_SUBSTITUTIONS = {
    "var": "LaunchConfiguration",
    "env": "EnvironmentVariable",
    "dirname": "ThisLaunchFileDir",
    "filename": "ThisLaunchFile",
    "find-pkg-share": "FindPackageShare",
    "find-pkg-prefix": "FindPackagePrefix",
    "exec-in-pkg": "ExecutableInPackage",
    "not": "NotSubstitution",
    "and": "AndSubstitution",
    "or": "OrSubstitution",
    "equals": "EqualsSubstitution",
    "not-equals": "NotEqualsSubstitution",
}


def _substitution(part: Subst) -> str:
    arguments = [_text_expr(argument) for argument in part.args]
    if part.kind == "env" and len(arguments) == 2:
        return f"EnvironmentVariable({arguments[0]}, default_value={arguments[1]})"
    if part.kind == "exec-in-pkg":  # $(exec-in-pkg EXE PKG)
        return f"ExecutableInPackage({arguments[0]}, {arguments[1]})"
    if part.kind not in _SUBSTITUTIONS:  # the reader refuses others before this runs
        raise ValueError(f"substitution $({part.kind}) has no Python equivalent here")
    return f"{_SUBSTITUTIONS[part.kind]}({', '.join(arguments)})"
