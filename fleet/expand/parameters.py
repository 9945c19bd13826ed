"""Merging a robot's parameters from their layers, remembering where each value came from.

Precedence, lowest first: the template's node defaults < the spec's `defaults.parameters` <
the robot's own `parameters` < `--set robot.node.param=value`.  We merge here, in Python, and
write one fully-qualified section per node, rather than relying on wildcard precedence inside
rcl (in Jazzy the last matching key applied wins, not the most specific).
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass
from functools import partial
from typing import Any

from fleet.errors import Location, SpecError, did_you_mean
from fleet.rules import node_key_problem, parameter_token_problem
from fleet.spec.params import coerce_like, command_line_value, flatten, namespace_clash
from fleet.spec.yaml_source import DocPath

LAYERS = ("template", "defaults", "robot", "--set")
# Above them all, outside the parameter file: a value the launch file gives a node inline after it.
INLINE_LAYER = "launch file"


@dataclass(frozen=True)
class Setting:
    """One value of one parameter in one layer."""

    value: Any
    layer: str  # one of LAYERS
    where: str | Callable[[], str]  # file:line or the --set argument; a callable is asked only when shown

    @property
    def source(self) -> str:
        return self.where() if callable(self.where) else self.where


@dataclass(frozen=True)
class Override:
    """A parsed `--set robot.node.param=value`."""

    robot: str
    node: str
    parameter: str
    value: Any
    text: str


def parse_override(text: str) -> Override:
    where = Location(f"--set {text}")
    key, equals, raw = text.partition("=")
    parts = key.strip().split(".", 2)
    if not equals or len(parts) < 3 or not all(parts):
        raise SpecError("expected ROBOT.NODE.PARAMETER=VALUE, e.g. robot1.controller.max_speed=0.8", where)
    try:
        value = command_line_value(raw)
    except ValueError as error:
        raise SpecError(str(error), where) from None
    # The names a spec's parameters must have (fleet.spec.load.check_parameters), and its values.
    if problem := node_key_problem(parts[1]):
        raise SpecError(f"node name {problem}", where)
    for token in parts[2].split("."):
        if problem := parameter_token_problem(token):
            raise SpecError(f"parameter name {parts[2]}: {problem}", where)
    return Override(robot=parts[0], node=parts[1], parameter=parts[2], value=value, text=text)


class ParameterLayers:
    """Effective parameters of one robot, and the history of every value."""

    def __init__(self) -> None:
        self.history: dict[tuple[str, str], list[Setting]] = {}
        # node -> dotted parameter names of the template's defaults, for typo warnings
        self.template_names: dict[str, frozenset[str]] = {}
        # Nodes the template's processes host besides the nodes its launch file starts, by their
        # names relative to the robot's namespace (local_costmap/local_costmap), in file order.
        self.hosted: tuple[str, ...] = ()
        # A copy knows what it was copied from and which nodes it changed since: the parameters of
        # the other nodes are its origin's, so their checks and files are made once, not per robot.
        self.origin: ParameterLayers | None = None
        self.changed: set[str] = set()

    def copy(self) -> ParameterLayers:
        other = ParameterLayers()
        other.history = dict(self.history)  # the lists are shared: set() replaces a list, never appends to one
        other.template_names = self.template_names
        other.hosted = self.hosted
        other.origin = self
        return other

    def same_as_origin(self, node: str | None = None) -> bool:
        """True when this copy's parameters (of `node`, or of every node) are still its origin's."""
        return self.origin is not None and (node not in self.changed if node is not None else not self.changed)

    def add(self, node: str, parameters: dict[str, Any], layer: str, source: Callable[[DocPath], str]) -> None:
        """Add a layer's values; source(key_path) says where each one is written (located lazily:
        a big fleet has tens of thousands of values and only --explain and errors show places)."""
        for name, (key_path, value) in flatten(parameters).items():
            self.set(node, name, value, layer, partial(source, key_path))

    def set(self, node: str, name: str, value: Any, layer: str, source: str | Callable[[], str]) -> None:
        self.changed.add(node)
        settings = self.history.get((node, name), [])
        reference = settings[0].value if settings else None
        self.history[(node, name)] = [*settings, Setting(coerce_like(value, reference), layer, source)]

    def effective(self) -> dict[str, dict[str, Any]]:
        """node -> dotted parameter name -> winning value."""
        result: dict[str, dict[str, Any]] = {}
        for (node, name), settings in self.history.items():
            result.setdefault(node, {})[name] = settings[-1].value
        return result

    def effective_of(self, node: str) -> dict[str, Any]:
        """Dotted parameter name -> winning value, for one node."""
        return {name: settings[-1].value for (of, name), settings in self.history.items() if of == node}

    def explain(self, node: str, name: str) -> list[Setting]:
        return list(self.history.get((node, name), []))

    def of_nodes(self, nodes: Collection[str] | None = None) -> Iterable[tuple[tuple[str, str], list[Setting]]]:
        """The history of every node's parameters, or only of `nodes`' ones."""
        if nodes is None:
            return self.history.items()
        return ((key, settings) for key, settings in self.history.items() if key[0] in nodes)

    def group_of(self, node: str, name: str) -> list[str]:
        """The parameters of `node` in the group `name` (FollowPath: FollowPath.plugin, ...)."""
        prefix = name + "."
        return [of_name for (of, of_name) in self.history if of == node and of_name.startswith(prefix)]

    def unknown_to_template(self, nodes: Collection[str] | None = None) -> dict[tuple[str, str], str]:
        """(node, dotted name) -> a warning, for each parameter the template's defaults of a node
        do not have (a likely typo), with the closest name they have."""
        warnings = {}
        for (node, name), settings in self.of_nodes(nodes):
            declared = self.template_names.get(node)
            if declared and name not in declared:
                guess = did_you_mean(name, declared)
                warnings[(node, name)] = (
                    f"{settings[-1].source}: {node}.{name} is not a parameter of the template's {node} defaults{guess}"
                )
        return warnings


def check_type_stable(layers: ParameterLayers, robot: str, nodes: Collection[str] | None = None) -> None:
    """A layer may change a value, not its type: the node declares one type per parameter."""
    for (node, name), settings in layers.of_nodes(nodes):
        first = settings[0]
        for later in settings[1:]:
            if _type_name(later.value) != _type_name(first.value):
                raise SpecError(
                    f"robot {robot}: {node}.{name} is {_type_name(first.value)} in the {first.layer} layer "
                    f"({first.source}) but {_type_name(later.value)} here",
                    Location(later.source),
                )


def check_names_disjoint(layers: ParameterLayers, robot: str, nodes: Collection[str] | None = None) -> None:
    """No parameter is also the namespace of another (`pid` and `pid.kp`), across all layers."""
    names_by_node: dict[str, list[str]] = {}
    for (node, name), _ in layers.of_nodes(nodes):
        names_by_node.setdefault(node, []).append(name)
    for node, names in names_by_node.items():
        clash = namespace_clash(names)
        if clash is None:
            continue
        first, second = (layers.history[(node, name)][-1] for name in clash)
        later = max(first, second, key=lambda setting: LAYERS.index(setting.layer))
        raise SpecError(
            f"robot {robot}: {node}.{clash[0]} is a parameter in the {first.layer} layer ({first.source}) and "
            f"the namespace of {node}.{clash[1]} in the {second.layer} layer ({second.source}): ROS cannot hold both",
            Location(later.source),
        )


def _type_name(value: Any) -> str:
    if isinstance(value, list):
        return f"list of {_type_name(value[0])}" if value else "list"
    return {bool: "bool", int: "int", float: "float", str: "string"}.get(type(value), type(value).__name__)
