"""What every fleet node shares: parameter declaration and checking, diagnostics, and the
run/spin/shutdown loop of an executable.

A node subclasses FleetNode, lists its parameters as ParamSpecs and its checks of them together
as Rules (both in the pure module fleet.nodes.parameters, which `fleet render` checks values by
too), may add a reaction to live changes (on_parameters_changed), and reports its state through
diagnose().  run() turns node factories into a process that exits 0 when asked to stop
and 2 with a one-line reason when its configuration is invalid.
"""

from __future__ import annotations

import math
import signal
import sys
from collections.abc import Callable, Iterable, Sequence
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions

from fleet.nodes.batch_executor import BatchExecutor
from fleet.nodes.parameters import ParamSpec, Rule, refusal

OK = DiagnosticStatus.OK
WARN = DiagnosticStatus.WARN
ERROR = DiagnosticStatus.ERROR

DIAGNOSTICS_PERIOD = 1.0  # s, wall time (see FleetNode.__init__)
EXIT_INVALID_CONFIG = 2


class ParameterError(Exception):
    """A parameter given at start-up is unusable; the message says which and why."""


class FleetNode(Node):
    """A Node with checked parameters (cached in self.params) and 1 Hz diagnostics."""

    PARAMETERS: Sequence[ParamSpec] = ()
    RULES: Sequence[Rule] = ()

    def __init__(self, default_name: str, **node_kwargs: Any) -> None:
        super().__init__(default_name, **node_kwargs)
        self._specs = {spec.name: spec for spec in self.PARAMETERS}
        try:
            self.params: dict[str, Any] = self._declare_all()
        except ParameterError:
            self.destroy_node()  # the caller never gets this node, so release it here
            raise
        self.add_pre_set_parameters_callback(self._coerce_parameters)
        self.add_on_set_parameters_callback(self._check_parameters)
        self.add_post_set_parameters_callback(self._apply_parameters)
        self._diagnostics_pub = self.create_publisher(DiagnosticArray, "diagnostics", 10)
        # Diagnostics run on wall (steady) time: a node waiting for /clock under use_sim_time is
        # still visibly alive and can say so, whereas its sim-time timers are all stopped.
        self._diagnostics_timer = self.create_timer(
            DIAGNOSTICS_PERIOD,
            self.publish_diagnostics,
            clock=Clock(clock_type=ClockType.STEADY_TIME),
        )
        self._logged_state: str | None = None
        self.get_logger().info("started: " + ", ".join(f"{k}={format_value(v)}" for k, v in self.params.items()))

    # -- parameters -----------------------------------------------------------------------

    def _declare_all(self) -> dict[str, Any]:
        # rclpy offers no public way to read a node's overrides (--params-file, -p) before the
        # declaration applies them; _parameter_overrides has been the attribute since Foxy.
        overrides = getattr(self, "_parameter_overrides", {})
        for spec in self.PARAMETERS:
            given = overrides.get(spec.name)
            value = spec.default if given is None else spec.coerce(given.value)
            if given is not None and value is not given.value:
                overrides[spec.name] = Parameter(spec.name, value=value)
            try:
                self.declare_parameter(spec.name, spec.default, spec.descriptor())
            except (InvalidParameterTypeException, InvalidParameterValueException):
                raise ParameterError(f"{self.get_fully_qualified_name()}: {spec.explain(value)}") from None
        values = {spec.name: self.get_parameter(spec.name).value for spec in self.PARAMETERS}
        reason = self.validate(values)
        if reason:
            raise ParameterError(f"{self.get_fully_qualified_name()}: {reason}")
        return values

    def validate(self, values: dict[str, Any]) -> str | None:
        """Checks a range cannot express (lengths, one parameter against another): the node's
        RULES, which `fleet render` checks a robot's values by too.

        Returns the reason for refusing values, or None to accept them.
        """
        return refusal(self.RULES, values)

    def on_parameters_changed(self, names: set[str]) -> None:
        """Called after a live change was accepted and self.params updated."""

    def _coerce_parameters(self, parameters: list[Parameter]) -> list[Parameter]:
        result = []
        for param in parameters:
            spec = self._specs.get(param.name)
            value = spec.coerce(param.value) if spec else param.value
            result.append(param if value is param.value else Parameter(param.name, value=value))
        return result

    def _check_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        # Ranges and types were already checked by the descriptors; check the whole resulting set.
        proposed = dict(self.params)
        proposed.update({p.name: p.value for p in parameters if p.name in self._specs})
        reason = self.validate(proposed)
        return SetParametersResult(successful=reason is None, reason=reason or "")

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        changed = {p.name for p in parameters if p.name in self._specs}
        for param in parameters:
            if param.name in self._specs:
                self.params[param.name] = param.value
                self.get_logger().info(f"parameter {param.name} set to {format_value(param.value)}")
        if changed:
            self.on_parameters_changed(changed)

    # -- diagnostics ----------------------------------------------------------------------

    def diagnose(self) -> tuple[int, str, dict[str, Any]]:
        """(level, message, key/values) describing the node now."""
        return OK, "running", {}

    def publish_diagnostics(self) -> None:
        level, message, values = self.diagnose()
        self._log_state_change(level, message)
        status = DiagnosticStatus(
            level=level,
            name=self.get_fully_qualified_name(),
            message=message,
            hardware_id=self.get_namespace().strip("/") or self.get_name(),
            values=[KeyValue(key=k, value=format_value(v)) for k, v in values.items()],
        )
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self._diagnostics_pub.publish(array)

    def _log_state_change(self, level: int, message: str) -> None:
        # The diagnostics message is the node's state in words ("driving", "blocked: obstacle at
        # 0.31 m"); a change of it is what a person reading `fleet logs` wants to see.
        state = message.split(":")[0]
        if state == self._logged_state:
            return
        self._logged_state = state
        # rclpy refuses one call site logging at several severities: one call per level.
        if level == OK:
            self.get_logger().info(message)
        elif level == WARN:
            self.get_logger().warning(message)
        else:
            self.get_logger().error(message)

    def sim_time_waiting(self) -> bool:
        """True while use_sim_time is on and no /clock has arrived (ROS time still zero)."""
        return self.get_clock().now().nanoseconds == 0


def format_value(value: Any) -> str:
    if isinstance(value, float):
        return "inf" if math.isinf(value) else f"{value:.4g}"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def seconds(node: Node) -> float:
    """The node's clock (sim time under use_sim_time) in seconds."""
    return node.get_clock().now().nanoseconds * 1e-9


# -- running ------------------------------------------------------------------------------


STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)
STOP_LATENCY = 0.2  # s: longest a requested stop waits for the executor to come back


def run(program: str, init_args: list[str], factories: Iterable[Callable[[], Node]]) -> int:
    """Init rclpy, build the nodes, spin them in one executor until SIGINT/SIGTERM.

    Returns the process exit code: 0 after a requested stop, 2 (with a one-line reason on
    stderr) when a node cannot start with the configuration it was given.
    """
    # Our own handlers only note the request; the loop below then stops between callbacks.
    # rclpy's handlers instead shut the context down from another thread, which races with a
    # running executor or callback (seen: RCLError "context is not valid" and exit 1 on SIGTERM).
    stop_requested: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, _: stop_requested.append(signum)) for sig in STOP_SIGNALS}
    try:
        rclpy.init(args=init_args, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as exc:  # e.g. an unreadable or malformed --params-file
        _restore(previous)
        return _fail(program, f"cannot start ROS: {_one_line(exc)}")
    nodes: list[Node] = []
    executor = None
    try:
        try:
            for factory in factories:
                nodes.append(factory())
        except ParameterError as exc:
            return _fail(program, str(exc))
        except Exception as exc:  # invalid names or remappings in the arguments, mostly
            return _fail(program, _one_line(exc))
        executor = BatchExecutor()  # as a host's: an exception in a callback ends the process
        for node in nodes:
            executor.add_node(node)
        while not stop_requested and rclpy.ok():
            executor.spin_once(timeout_sec=STOP_LATENCY)
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown()
        _restore(previous)
    return 0


def _restore(handlers: dict) -> None:
    for sig, handler in handlers.items():
        signal.signal(sig, handler)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text


def _fail(program: str, reason: str) -> int:
    print(f"{program}: error: {reason}", file=sys.stderr, flush=True)
    return EXIT_INVALID_CONFIG


def main_for(node_class: type[FleetNode], program: str, argv: list[str] | None) -> int:
    """main() of a single-node executable: ROS arguments come from argv (default sys.argv)."""
    args = list(sys.argv if argv is None else argv)
    return run(program, args, [node_class])
