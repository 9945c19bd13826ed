"""The parameters fleet's nodes (package fleet_nodes) declare, and what values a node takes at
start: each of the declared type, within the declared range (ParamSpec), and all of them together
passing the node's checks that a range cannot express (Rule: waypoints in x,y pairs, the battery's
critical threshold at most its low one).

Pure (no rclpy at import): the nodes declare these and check by these rules, at start and on
every live change (fleet.nodes.common.FleetNode), and `fleet render` refuses by the same
declarations and rules what a node would refuse when it starts (fleet.expand.expansion), so the
two cannot drift apart.  The declarations follow rclpy's own rules for a declared parameter
(rclpy.node.Node._apply_descriptor), which tests/nodes compare them with.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from fleet.rules import ros_type
from fleet.runtime.ament import PACKAGE

if TYPE_CHECKING:
    from rcl_interfaces.msg import ParameterDescriptor

# rclpy.node.Node.PARAM_REL_TOL: a double this close to a bound counts as on it.
PARAM_REL_TOL = 1e-6


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter.  Its ROS type follows the default's Python type."""

    name: str
    default: Any
    description: str
    low: float | int | None = None  # inclusive bounds, enforced by the descriptor
    high: float | int | None = None

    def descriptor(self) -> ParameterDescriptor:
        from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
        from rclpy.parameter import Parameter

        param_type = Parameter.Type.from_parameter_value(self.default)
        descriptor = ParameterDescriptor(name=self.name, type=param_type.value, description=self.description)
        # Bounds come in pairs (low and high, or neither).
        if self.low is not None and self.high is not None and param_type == Parameter.Type.DOUBLE:
            descriptor.floating_point_range = [
                FloatingPointRange(from_value=float(self.low), to_value=float(self.high), step=0.0)
            ]
        elif self.low is not None and self.high is not None and param_type == Parameter.Type.INTEGER:
            descriptor.integer_range = [IntegerRange(from_value=int(self.low), to_value=int(self.high), step=0)]
        return descriptor

    def coerce(self, value: Any) -> Any:
        """Integers where doubles are declared become doubles.

        YAML and command lines write `max_speed: 1` as an integer, and rcl would refuse it for a
        double parameter with a type error people find baffling; the value is unambiguous.
        """
        if isinstance(self.default, float) and isinstance(value, int) and not isinstance(value, bool):
            return float(value)
        if (
            isinstance(self.default, list)
            and self.default
            and isinstance(self.default[0], float)
            and isinstance(value, (list, tuple))
            and value
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value)
        ):
            return [float(v) for v in value]
        return value

    def problem(self, value: Any) -> str | None:
        """Why the node refuses `value` at start (after coerce, as the node does): of another type
        than declared, or out of the declared range; None when the declaration takes it.  Words
        to follow the parameter's name: "= 9.0 is out of range 0.0 .. 5.0"."""
        value = self.coerce(value)
        expected, given = ros_type(self.default), ros_type(value)
        if given != expected:
            return f"must be of type {expected}, got {given} {value!r}"
        if given in ("double", "integer") and _out_of_range(value, self.low, self.high, given == "double"):
            return f"= {value!r} is out of range {self.low} .. {self.high}"
        return None

    def explain(self, value: Any) -> str:
        """Why value was refused, in words a user can act on."""
        return f"parameter '{self.name}' {self.problem(value) or f'= {value!r} refused'}"


def _out_of_range(value: float | int, low: float | int | None, high: float | int | None, double: bool) -> bool:
    """rclpy's range check (Node._apply_floating_point_range and _apply_integer_range, step 0),
    for a declaration with both bounds (only those get a range): the bounds are in, a double
    within PARAM_REL_TOL of one too; NaN is out."""
    if low is None or high is None:
        return False
    if double:
        lowest, highest = sorted((float(low), float(high)))
        if math.isclose(value, lowest, rel_tol=PARAM_REL_TOL) or math.isclose(value, highest, rel_tol=PARAM_REL_TOL):
            return False
    else:
        lowest, highest = sorted((int(low), int(high)))
        if value in (lowest, highest):
            return False
    return not lowest < value < highest


CONTROLLER = (
    ParamSpec(
        "waypoints",
        [2.0, 0.0, 2.0, 2.0, 0.0, 2.0, 0.0, 0.0],
        "Route as a flat list of x,y pairs in the odometry frame (m); even length >= 2",
    ),
    ParamSpec("loop", True, "After the last waypoint start again at the first (else stop)"),
    ParamSpec("max_speed", 0.5, "Forward speed limit (m/s)", 0.0, 5.0),
    ParamSpec("max_turn_rate", 1.5, "Turn rate limit (rad/s)", 0.0, 10.0),
    ParamSpec("goal_tolerance", 0.15, "Distance at which a waypoint counts as reached (m)", 0.01, 5.0),
    ParamSpec("control_rate", 20.0, "Control loop rate (Hz of the node clock)", 1.0, 200.0),
)

BATTERY = (
    ParamSpec("capacity", 100.0, "Energy of a full battery (Wh); > 0", 0.0, 100000.0),
    ParamSpec("initial_percentage", 1.0, "Charge at start-up (fraction 0..1)", 0.0, 1.0),
    ParamSpec("idle_draw", 5.0, "Power drawn at all times (W)", 0.0, 10000.0),
    ParamSpec("motion_draw", 20.0, "Extra power per m/s of odometry speed (W per m/s)", 0.0, 10000.0),
    ParamSpec("low_threshold", 0.2, "Charge below which diagnostics warn (fraction)", 0.0, 1.0),
    ParamSpec(
        "critical_threshold",
        0.05,
        "Charge below which health is DEAD (fraction); <= low_threshold",
        0.0,
        1.0,
    ),
    ParamSpec("publish_rate", 1.0, "Rate of the battery topic (Hz of the node clock)", 0.1, 100.0),
)

SAFETY = (
    ParamSpec("safety_distance", 0.4, "Block forward motion closer than this (m)", 0.0, 10.0),
    ParamSpec("scan_half_angle", 0.6, "Half width of the forward cone checked (rad)", 0.0, 3.1416),
    ParamSpec("scan_timeout", 1.0, "Zero output when no scan came for this long (s)", 0.05, 60.0),
)


@dataclass(frozen=True)
class Rule:
    """A check a node makes of its parameters that their declarations cannot express: a length, a
    bound that is not in, one parameter against another.  It is given the values of `names` (of
    their declared types and in range: the node checks those first) and says what is wrong, in
    words to follow the first name ("must be x,y pairs ..."), or None."""

    names: tuple[str, ...]  # the parameters it reads; the first is the one its words are about
    check: Callable[..., str | None]

    def problem(self, values: Mapping[str, Any]) -> str | None:
        return self.check(*(values[name] for name in self.names))


def _waypoints_problem(waypoints: Sequence[float]) -> str | None:
    if len(waypoints) < 2 or len(waypoints) % 2:
        return f"must be x,y pairs (even length >= 2), got {len(waypoints)} values"
    if not all(math.isfinite(v) for v in waypoints):
        return "must be finite numbers"
    return None


def _capacity_problem(capacity: float) -> str | None:
    # A battery of no capacity has no charge fraction (the model divides by it), and the declared
    # range cannot say so: rclpy's ranges include their bounds.
    return None if capacity > 0.0 else f"must be > 0, got {capacity!r}"


def _thresholds_problem(critical: float, low: float) -> str | None:
    return None if critical <= low else f"({critical!r}) must be <= low_threshold ({low!r})"


CONTROLLER_RULES = (Rule(("waypoints",), _waypoints_problem),)
BATTERY_RULES = (
    Rule(("capacity",), _capacity_problem),
    Rule(("critical_threshold", "low_threshold"), _thresholds_problem),
)
SAFETY_RULES: tuple[Rule, ...] = ()


def refusal(rules: Sequence[Rule], values: Mapping[str, Any]) -> str | None:
    """Why a node refuses `values` (every parameter it declares) by its `rules`, in the words it
    says it in ("waypoints must be x,y pairs ..."); None when it takes them."""
    for rule in rules:
        if (problem := rule.problem(values)) is not None:
            return f"{rule.names[0]} {problem}"
    return None


# Executable name (fleet.nodes.NODES) -> parameter name -> its declaration.
_DECLARED: dict[str, dict[str, ParamSpec]] = {
    executable: {spec.name: spec for spec in specs}
    for executable, specs in (("controller", CONTROLLER), ("battery", BATTERY), ("safety", SAFETY))
}


_RULES: dict[str, tuple[Rule, ...]] = {
    "controller": CONTROLLER_RULES,
    "battery": BATTERY_RULES,
    "safety": SAFETY_RULES,
}


def declared(package: str, executable: str) -> dict[str, ParamSpec] | None:
    """The parameters a node started as `package` `executable` declares, by name; None for a
    node of another package (or an executable fleet_nodes has not), whose parameters fleet
    cannot know."""
    return _DECLARED.get(executable) if package == PACKAGE else None


def rules(package: str, executable: str) -> tuple[Rule, ...]:
    """The checks of its parameters together a node started as `package` `executable` makes at
    start (none for a node of another package: fleet cannot know them)."""
    return _RULES.get(executable, ()) if package == PACKAGE else ()
