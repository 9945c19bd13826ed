"""A launch file as the reader understands it: one dataclass per action, attributes still holding
their substitutions (fleet.launchfile.substitutions.Text), each with where it was written."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from fleet.errors import Location
from fleet.launchfile.substitutions import Text

# A parameter value as written: substitution text (typed when evaluated, as launch_ros does),
# a YAML scalar already typed by the file, or a list of those.
ParamValue = Any


@dataclass
class Condition:
    keyword: str  # if | unless
    text: Text


@dataclass
class Action:
    where: Location
    condition: Condition | None


@dataclass
class DeclareArgument(Action):
    name: str
    default: Text | None
    description: str | None = None
    choices: tuple[str, ...] | None = None


@dataclass
class SetConfiguration(Action):  # let
    name: Text
    value: Text


@dataclass
class SetEnv(Action):
    name: Text
    value: Text


@dataclass
class UnsetEnv(Action):
    name: Text


@dataclass
class PushNamespace(Action):
    namespace: Text


@dataclass
class Group(Action):
    actions: list[Action]
    scoped: bool | Text  # Text: launch_yaml passes a string on; see reader
    forwarding: bool = True
    keep: list[tuple[Text, Text]] = field(default_factory=list)


@dataclass
class Include(Action):
    file: Text
    arguments: list[tuple[Text, Text]]


@dataclass
class Timer(Action):
    period: float | Text
    actions: list[Action]


@dataclass
class Log(Action):
    message: Text


@dataclass
class ParamFile:
    path: Text
    where: Location


@dataclass
class InlineParam:
    name: Text
    value: ParamValue  # or, for nested params, a list of InlineParam
    where: Location
    nested: bool = False


@dataclass
class SetParameter(Action):
    name: Text
    value: ParamValue


@dataclass
class SetRemap(Action):
    source: Text
    target: Text


@dataclass
class Process(Action):
    """What `executable` and `node` share (launch's ExecuteProcess)."""

    env: list[tuple[Text, Text]]
    respawn: Text | None
    respawn_delay: float
    output: Text | None
    name: Text | None  # executable: the process name; node: the node name


@dataclass
class Executable(Process):
    cmd: Text = ()
    cwd: Text | None = None


@dataclass
class Node(Process):
    package: Text = ()
    executable: Text = ()
    namespace: Text | None = None
    exec_name: Text | None = None
    params: list[ParamFile | InlineParam] = field(default_factory=list)
    remaps: list[tuple[Text, Text]] = field(default_factory=list)
    args: Text | None = None
    ros_args: Text | None = None


@dataclass
class LaunchDescription:
    path: Path
    actions: list[Action]
