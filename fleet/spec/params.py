"""ROS parameter values: what ROS can hold, and flattening of nested parameter maps.

ROS parameters are bool, int, float, str, or homogeneous non-empty lists of one of those (values
are typed as rcl types them when read: fleet.spec.rcl_types, fleet.spec.yaml_source).
A nested mapping inside a node's parameters is a parameter namespace (`pid: {kp: 1}` is the
parameter `pid.kp`), exactly as rcl reads parameter files.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from fleet.spec.rcl_types import sequence_problem
from fleet.spec.yaml_source import DocPath, parse_parameter_value

SCALAR_TYPES = (bool, int, float, str)


def value_problem(value: Any) -> str | None:
    """Why ROS cannot hold `value` as a parameter, or None when it can."""
    if value is None:
        return "null is not a ROS parameter value (give a value, or remove the key)"
    if isinstance(value, SCALAR_TYPES):
        return None
    if isinstance(value, list):
        for item in value:
            if isinstance(item, list):
                return "nested lists are not ROS parameter values"
            if isinstance(item, dict):
                return "mappings inside lists are not ROS parameter values"
            if item is None:
                return "null inside a list is not a ROS parameter value"
        if problem := sequence_problem(value):
            # rcl refuses [1, 2.5] ("Sequence should be of same type"): no int is taken for a double.
            return f"mixed-type list: {problem} (write 1.0 for a double)" if value else problem
        return None
    return f"{type(value).__name__} is not a ROS parameter value"


def command_line_value(text: str) -> Any:
    """A parameter value given on the command line (`--set`, `fleet param set`), typed as rcl types
    one in a parameter file (`1e-1` a double, `no` a bool; nothing at all is an empty string, as
    `ros2 param set` makes it); raises ValueError saying why it is not one ROS can hold."""
    value = parse_parameter_value(text)
    if problem := value_problem(value):
        raise ValueError(problem)
    return value


class ParameterNameClash(ValueError):
    """Two keys of one node's parameters that name the same parameter."""

    def __init__(self, name: str, key_path: DocPath):
        super().__init__(f"{name} is written twice (once as a dotted key, once nested)")
        self.name = name
        self.key_path = key_path


def flatten(parameters: dict[str, Any], prefix: str = "") -> dict[str, tuple[DocPath, Any]]:
    """{"pid": {"kp": 1}} -> {"pid.kp": (("pid", "kp"), 1)}: dotted name -> (key path, value).
    Raises ParameterNameClash when a dotted key and a nested one name the same parameter."""
    flat: dict[str, tuple[DocPath, Any]] = {}
    for key, value in parameters.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            for sub_name, (sub_path, sub_value) in flatten(value, name + ".").items():
                _put(flat, sub_name, ((key, *sub_path), sub_value))
        else:
            _put(flat, name, ((key,), value))
    return flat


def _put(flat: dict[str, tuple[DocPath, Any]], name: str, entry: tuple[DocPath, Any]) -> None:
    if name in flat:
        raise ParameterNameClash(name, entry[0])
    flat[name] = entry


def namespace_clash(names: Iterable[str]) -> tuple[str, str] | None:
    """(a, b) when parameter a is also the namespace of parameter b (`pid` and `pid.kp`): a
    parameter file cannot hold both.  None when there is no such pair."""
    names = {name for name in names}
    if not any("." in name for name in names):
        return None
    for name in names:
        parts = name.split(".")
        for end in range(1, len(parts)):
            prefix = ".".join(parts[:end])
            if prefix in names:
                return prefix, name
    return None


def unflatten(flat: dict[str, Any]) -> dict[str, Any]:
    """{"pid.kp": 1} -> {"pid": {"kp": 1}} for writing readable parameter files."""
    tree: dict[str, Any] = {}
    for name, value in flat.items():
        parts = name.split(".")
        node = tree
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    return tree


def coerce_like(value: Any, reference: Any) -> Any:
    """Promote ints to floats where the reference (the template's default) is a float.

    People write `max_speed: 1` or `waypoints: [2, 0, 2, 2]`; the node declares doubles and
    would refuse an integer.  Only this lossless promotion is done: nothing else changes type.
    """
    if isinstance(reference, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(reference, list) and reference and isinstance(reference[0], float) and isinstance(value, list):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value]
    return value
