"""The nodes' checks of their parameters together (fleet.nodes.parameters' rules), pure: the nodes
check by them at start and on every live change, and `fleet render` by the same ones
(tests/expand/test_render_node_parameters.py; tests/nodes/test_param_declarations.py asks the
nodes themselves)."""

from __future__ import annotations

import math

import pytest

from fleet.nodes import NODES, parameters
from fleet.runtime.ament import PACKAGE

DEFAULTS = {
    executable: {name: spec.default for name, spec in (parameters.declared(PACKAGE, executable) or {}).items()}
    for executable in NODES
}


def refusal(executable: str, **given) -> str | None:
    return parameters.refusal(parameters.rules(PACKAGE, executable), {**DEFAULTS[executable], **given})


@pytest.mark.parametrize("executable", sorted(NODES))
def test_each_nodes_defaults_pass_its_rules(executable):
    """Render checks a rule only when a value it reads is given: a node's defaults alone pass."""
    assert refusal(executable) is None


@pytest.mark.parametrize(
    "waypoints, words",
    [
        ([1.0, 2.0], None),
        ([], "waypoints must be x,y pairs (even length >= 2), got 0 values"),
        ([1.0], "waypoints must be x,y pairs (even length >= 2), got 1 values"),
        ([1.0, 2.0, 3.0], "waypoints must be x,y pairs (even length >= 2), got 3 values"),
        ([1.0, math.nan], "waypoints must be finite numbers"),
        ([1.0, 2.0, math.inf, 0.0], "waypoints must be finite numbers"),
    ],
)
def test_the_controller_takes_waypoints_in_finite_x_y_pairs(waypoints, words):
    assert refusal("controller", waypoints=waypoints) == words


@pytest.mark.parametrize(
    "given, words",
    [
        ({"capacity": 0.0}, "capacity must be > 0, got 0.0"),  # in the declared range, whose bounds are in
        ({"capacity": 1e-9}, None),
        ({"critical_threshold": 0.5}, "critical_threshold (0.5) must be <= low_threshold (0.2)"),
        ({"low_threshold": 0.01}, "critical_threshold (0.05) must be <= low_threshold (0.01)"),
        ({"critical_threshold": 0.3, "low_threshold": 0.3}, None),
        ({"critical_threshold": 0.0, "low_threshold": 0.0}, None),
    ],
)
def test_the_battery_takes_a_capacity_and_its_critical_threshold_at_most_its_low_one(given, words):
    assert refusal("battery", **given) == words


def test_nodes_of_other_packages_have_no_rules_fleet_knows():
    assert parameters.rules("vendor_nav", "controller") == ()
    assert parameters.rules(PACKAGE, "no_such_node") == ()
    assert parameters.rules(PACKAGE, "safety") == ()
