"""fleet.nodes.parameters says, without rclpy, which values the nodes refuse at start (`fleet
render` refuses by it): here each node's real declaration, in rclpy, is asked the same, and each
node is given values its rules (of its parameters together) refuse and take."""

from __future__ import annotations

import math

import pytest

pytestmark = pytest.mark.integration

rclpy = pytest.importorskip("rclpy")

from rclpy.parameter import Parameter  # noqa: E402

from fleet.nodes import parameters  # noqa: E402
from fleet.nodes.battery import BatteryNode  # noqa: E402
from fleet.nodes.common import ParameterError  # noqa: E402
from fleet.nodes.controller import ControllerNode  # noqa: E402
from fleet.nodes.safety import SafetyNode  # noqa: E402
from fleet.rules import ros_type  # noqa: E402

NODES = [(ControllerNode, parameters.CONTROLLER), (BatteryNode, parameters.BATTERY), (SafetyNode, parameters.SAFETY)]


def candidates(spec: parameters.ParamSpec) -> list:
    """Values on, near and beyond the spec's bounds, and of other types."""
    values = [spec.default, "text", True, 3, [1.0, 2.0], ["a"]]
    if spec.low is not None and spec.high is not None:
        low, high = float(spec.low), float(spec.high)
        values += [low, high, int(high), low - 0.01, high + 0.01, high * (1 + 1e-7), high * (1 + 1e-5), -1e9, 1e9]
        values += [math.nan, math.inf]
    return values


def refusal(ros, node_class: type, given: dict) -> str | None:
    """What the node says when it refuses to start with the `given` values (by name), or None."""
    overrides = [Parameter(name, value=value) for name, value in given.items()]
    try:
        node = node_class(context=ros.context, parameter_overrides=overrides)
    except ParameterError as refused:
        return str(refused)
    node.destroy_node()
    return None


@pytest.mark.parametrize("node_class, specs", NODES, ids=lambda item: getattr(item, "__name__", ""))
def test_the_pure_declarations_refuse_what_the_nodes_refuse(ros, node_class, specs):
    assert tuple(node_class.PARAMETERS) == specs
    for spec in specs:
        for value in candidates(spec):
            refused = refusal(ros, node_class, {spec.name: value})
            problem = spec.problem(value)
            if problem is not None:
                assert refused is not None and refused.endswith(spec.explain(value)), (spec.name, value, refused)
            else:  # taken by the declaration; the node's own cross-parameter check may still refuse it
                assert refused is None or ("out of range" not in refused and "must be of type" not in refused), (
                    spec.name,
                    value,
                    refused,
                )


@pytest.mark.parametrize(
    "value", [None, True, 0, 1.5, "x", b"x", [True], [1, 2], [1.0], ["a"], [b"a"], (1, 2), [], [True, 1]]
)
def test_types_are_named_as_rclpy_names_them(value):
    try:
        expected = Parameter.Type.from_parameter_value(value).name.lower()
    except TypeError:
        expected = None
    if expected is not None:
        assert ros_type(value) == expected
    else:
        assert ros_type(value) == type(value).__name__


RULES = [
    (ControllerNode, parameters.CONTROLLER_RULES),
    (BatteryNode, parameters.BATTERY_RULES),
    (SafetyNode, parameters.SAFETY_RULES),
]
TOGETHER = [
    (ControllerNode, {"waypoints": [1.0, 2.0, 3.0]}),
    (ControllerNode, {"waypoints": [1.0]}),
    (ControllerNode, {"waypoints": [1.0, math.nan]}),
    (ControllerNode, {"waypoints": [1.0, 2.0]}),
    (BatteryNode, {"capacity": 0.0}),
    (BatteryNode, {"capacity": 1e-9}),
    (BatteryNode, {"critical_threshold": 0.5}),
    (BatteryNode, {"low_threshold": 0.01}),
    (BatteryNode, {"critical_threshold": 0.3, "low_threshold": 0.3}),
    (BatteryNode, {"critical_threshold": 0.9, "low_threshold": 0.95}),
]


@pytest.mark.parametrize("node_class, rules", RULES, ids=lambda item: getattr(item, "__name__", ""))
def test_the_nodes_check_by_the_pure_rules(node_class, rules):
    assert tuple(node_class.RULES) == rules


@pytest.mark.parametrize("node_class, given", TOGETHER, ids=lambda item: getattr(item, "__name__", str(item)))
def test_the_nodes_refuse_together_what_the_pure_rules_refuse(ros, node_class, given):
    values = {spec.name: spec.coerce(given.get(spec.name, spec.default)) for spec in node_class.PARAMETERS}
    expected = parameters.refusal(node_class.RULES, values)
    refused = refusal(ros, node_class, given)
    assert (refused is None) == (expected is None), (given, refused, expected)
    assert expected is None or (refused is not None and refused.endswith(expected)), (refused, expected)
