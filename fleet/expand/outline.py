"""What a rendered launch description declares: its arguments and its nodes.

The rendered text is read by the one launch reader (fleet.launchfile), the one the agents'
embedded runner uses, so render refuses exactly what an agent would refuse to run.  From the
description this takes, without running anything, the nodes' full names (for the per-namespace
parameter sections) and the top-level arguments (to check a robot's launch_args).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fleet.errors import LaunchFileError, Location, TemplateError
from fleet.expand.template_lines import source_line_of
from fleet.launchfile import description as d
from fleet.launchfile.reader import read_launch_document
from fleet.launchfile.substitutions import Text, literal
from fleet.launchfile.substitutions import written as _written
from fleet.spec.yaml_source import SourceMap


@dataclass(frozen=True)
class NodeOutline:
    name: str
    package: str
    executable: str
    namespace: str  # absolute, as far as it is literal
    conditional: bool  # has if/unless (or is under one)

    @property
    def fqn(self) -> str:
        return f"{self.namespace.rstrip('/')}/{self.name}"


@dataclass(frozen=True)
class LaunchOutline:
    arguments: dict[str, str]  # name -> default as written
    nodes: tuple[NodeOutline, ...]


def outline(
    data: Any, source: SourceMap, template_file: str | Path, path: Path | None = None, text: str | None = None
) -> tuple[LaunchOutline, d.LaunchDescription]:
    """Outline a rendered launch document (loaded by load_yaml); raises TemplateError when the
    runner would refuse it.  Also the description read, as the launch file at `path` (default:
    the template's).  With the rendered `text`, a refusal is placed at the template's line that
    wrote the refused one, when one line could have."""
    output = _Output(template_file, text)
    try:
        description = read_launch_document(data, source, path or Path(str(template_file)))
    except LaunchFileError as problem:
        raise _refused(problem.message, problem.location, output) from None
    arguments: dict[str, str] = {}
    for action in description.actions:
        if isinstance(action, d.DeclareArgument):
            arguments.setdefault(action.name, "" if action.default is None else _written(action.default))
    nodes: list[NodeOutline] = []
    # Two nodes of one name: the launch interpreter refuses them (check_rendered_launch).
    _walk(description.actions, "/", nodes, output, conditional=False)
    return LaunchOutline(arguments=arguments, nodes=tuple(nodes)), description


def _walk(actions: list[d.Action], namespace: str, nodes: list[NodeOutline], output: _Output, conditional: bool) -> str:
    """Follow the namespace as launch_ros would; returns the namespace after the actions."""
    for action in actions:
        under_condition = conditional or action.condition is not None
        if isinstance(action, d.Group):
            inner = _walk(action.actions, namespace, nodes, output, under_condition)
            if action.scoped is False:
                namespace = inner
        elif isinstance(action, d.Timer):
            _walk(action.actions, namespace, nodes, output, under_condition)
        elif isinstance(action, d.PushNamespace):
            pushed = _literal(action.namespace, "namespace", action.where, output)
            namespace = pushed if pushed.startswith("/") else f"{namespace.rstrip('/')}/{pushed}"
        elif isinstance(action, d.Node):
            if action.name is None:
                raise _refused("node is missing 'name'", action.where, output)
            name = _literal(action.name, "name", action.where, output)
            own = None if action.namespace is None else _literal(action.namespace, "namespace", action.where, output)
            if own is None:
                full = namespace
            elif own.startswith("/"):
                full = own
            else:
                full = f"{namespace.rstrip('/')}/{own}"
            nodes.append(
                NodeOutline(
                    name=name,
                    package=_written(action.package),
                    executable=_written(action.executable),
                    namespace=full,
                    conditional=under_condition,
                )
            )
    return namespace


def _literal(text: Text, key: str, place: Location | None, output: _Output) -> str:
    value = literal(text)
    if value is None:
        message = f"{key} {_written(text)!r} must be literal in a fleet template (no substitutions)"
        raise _refused(message, place, output)
    return value


@dataclass(frozen=True)
class _Output:
    """A rendered launch file being outlined: the template it came from, and its text if known."""

    template_file: str | Path
    text: str | None = None


def _refused(problem: str, place: Location | None, output: _Output) -> TemplateError:
    """A problem of the rendered launch file, told at the template with its line and column in
    the rendered output (`place`), which is what the reader knows, and at the template's line
    that wrote it when one line could have."""
    line = place.line if place else None
    at = f"line {line}, column {place.column} of its output: " if place and line else ""
    source_line = source_line_of(output.template_file, output.text, line) if output.text is not None else None
    return TemplateError(f"rendered launch file refused: {at}{problem}", Location(output.template_file, source_line))
