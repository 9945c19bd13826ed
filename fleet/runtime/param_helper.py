"""Get or set one ROS parameter of a running node, or list every parameter of some nodes, through
their parameter services.

Run by the agent as a subprocess, in the fleet's ROS environment (its ROS_DOMAIN_ID):

    python -m fleet.runtime.param_helper get /robot1/controller max_speed
    echo 0.8 | python -m fleet.runtime.param_helper set /robot1/controller max_speed   # value as JSON
    python -m fleet.runtime.param_helper list /robot1/controller /robot1/battery

Prints one JSON line: {"v": 1, "kind": "param_reply", "ok": ..., "value": ..., "reason": ...};
a list's has "parameters": {node: {name: value}} and "unanswered": {node: why}.
A set is typed after the parameter's current type (1 becomes 1.0 for a double, as people
expect); the node's own checks (ranges, read-only) decide, and its reason is passed back.
"""

from __future__ import annotations

import json
import sys
import time

from fleet.rules import HELPER_ROS_ARGS

SERVICE_TIMEOUT = 20.0


def _reply(ok: bool, value=None, reason: str = "", **more) -> None:
    reply = {"v": 1, "kind": "param_reply", "ok": ok, "value": value, "reason": reason, **more}
    print(json.dumps(reply), flush=True)


def _refused() -> str:
    """The reply code of a value the node refused (imported only then: the protocol's models cost
    the helper's every call an import otherwise)."""
    from fleet.wire.protocol import REFUSED

    return REFUSED


def _python_value(message):
    from rcl_interfaces.msg import ParameterType as T

    kinds = {
        T.PARAMETER_BOOL: "bool_value",
        T.PARAMETER_INTEGER: "integer_value",
        T.PARAMETER_DOUBLE: "double_value",
        T.PARAMETER_STRING: "string_value",
        T.PARAMETER_BOOL_ARRAY: "bool_array_value",
        T.PARAMETER_INTEGER_ARRAY: "integer_array_value",
        T.PARAMETER_DOUBLE_ARRAY: "double_array_value",
        T.PARAMETER_STRING_ARRAY: "string_array_value",
    }
    field = kinds.get(message.type)
    if field is None:
        return None
    value = getattr(message, field)
    return list(value) if field.endswith("array_value") else value


def _coerce(value, current_type: int):
    """Promote ints to floats where the parameter is a double (or double array)."""
    from rcl_interfaces.msg import ParameterType as T

    if current_type == T.PARAMETER_DOUBLE and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if current_type == T.PARAMETER_DOUBLE_ARRAY and isinstance(value, list):
        return [float(v) if isinstance(v, int) and not isinstance(v, bool) else v for v in value]
    return value


def _type_mismatch(held: int, given: int) -> str:
    """Why a node refused a value of another type than its parameter's, in the words of a YAML
    parameter file (a node that allows dynamic typing takes it instead)."""
    from rcl_interfaces.msg import ParameterType as T

    words = {
        T.PARAMETER_BOOL: "a bool (true or false)",
        T.PARAMETER_INTEGER: "an integer",
        T.PARAMETER_DOUBLE: "a double",
        T.PARAMETER_STRING: "a string",
        T.PARAMETER_BYTE_ARRAY: "a byte array",
        T.PARAMETER_BOOL_ARRAY: "a bool array",
        T.PARAMETER_INTEGER_ARRAY: "an integer array",
        T.PARAMETER_DOUBLE_ARRAY: "a double array",
        T.PARAMETER_STRING_ARRAY: "a string array",
    }
    reason = f"it holds {words.get(held, 'another type')}, and the value given is {words.get(given, 'another type')}"
    if held == T.PARAMETER_STRING:
        reason += " (quote it for a string: '\"...\"')"
    return reason


RESEND_PERIOD = 2.0  # s: a request unanswered this long is sent again (see call_service)


def call_service(client, request, spin_until, timeout: float):
    """Send `request` and wait for the answer; resend it every RESEND_PERIOD until `timeout`.
    Returns the response, or None when none came.

    Why resend: right after a node restarts, the service looks available because its previous
    process is still in the DDS graph until its lease runs out (seen: a restarted node's
    get_parameters went unanswered for 20 s while a second call, moments later, was answered).
    A request written before the new server has matched us is lost (services are volatile);
    the same request sent again once it has is answered.  Parameter gets and sets are
    idempotent, so a duplicate answer does no harm."""
    deadline = time.monotonic() + timeout
    while True:
        future = client.call_async(request)
        spin_until(future, max(0.0, min(RESEND_PERIOD, deadline - time.monotonic())))
        if future.done():
            return future.result()
        client.remove_pending_request(future)
        if time.monotonic() >= deadline:
            return None


def _call(node, service_type, name: str, request):
    import rclpy

    client = node.create_client(service_type, name)
    if not client.wait_for_service(timeout_sec=SERVICE_TIMEOUT):
        raise TimeoutError(f"service {name} is not available (is the node running?)")
    spin = lambda future, seconds: rclpy.spin_until_future_complete(node, future, timeout_sec=seconds)  # noqa: E731
    response = call_service(client, request, spin, SERVICE_TIMEOUT)
    if response is None:
        raise TimeoutError(f"no answer from {name}")
    return response


LIST_DISCOVERY = 10.0  # s: how long a list waits for every node's parameter services to appear


def _services_present(node, service_type, names: set[str], timeout: float) -> set[str]:
    """Those of the service `names` that answer, once all do or `timeout` has passed.  A client
    per service, not the graph: a discovery client (ROS_DISCOVERY_SERVER) sees only the
    endpoints that match its own."""
    import rclpy

    clients = {name: node.create_client(service_type, name) for name in names}
    deadline = time.monotonic() + timeout
    try:
        while True:
            present = {name for name, client in clients.items() if client.service_is_ready()}
            if present == names or time.monotonic() >= deadline:
                return present
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        for client in clients.values():
            node.destroy_client(client)


def _list(node, fqns: list[str]) -> None:
    """Every parameter of each node in `fqns`, with its value, like `ros2 param dump`.  A node
    without parameter services (not a ROS node, or not running) is named in "unanswered"; it
    costs one LIST_DISCOVERY wait for all such nodes, not SERVICE_TIMEOUT each."""
    from rcl_interfaces.srv import GetParameters, ListParameters

    present = _services_present(node, ListParameters, {f"{fqn}/list_parameters" for fqn in fqns}, LIST_DISCOVERY)
    parameters, unanswered = {}, {}
    for fqn in fqns:
        if f"{fqn}/list_parameters" not in present:
            unanswered[fqn] = "it has no parameter services (not a ROS node, or not running)"
            continue
        try:
            listed = _call(node, ListParameters, f"{fqn}/list_parameters", ListParameters.Request())
            names = sorted(listed.result.names)
            got = _call(node, GetParameters, f"{fqn}/get_parameters", GetParameters.Request(names=names))
        except TimeoutError as error:
            unanswered[fqn] = str(error)
            continue
        parameters[fqn] = {name: _python_value(value) for name, value in zip(names, got.values, strict=True)}
    _reply(True, parameters=parameters, unanswered=unanswered)


def _closest(node, fqn: str, name: str) -> str:
    """` (did you mean 'x'?)` from the node's own parameter names, or nothing (asked only after a
    miss, so a get or set that finds its parameter costs no extra call)."""
    from rcl_interfaces.srv import ListParameters

    from fleet.errors import did_you_mean

    try:
        listed = _call(node, ListParameters, f"{fqn}/list_parameters", ListParameters.Request())
    except TimeoutError:
        return ""
    return did_you_mean(name, listed.result.names)


def main(argv: list[str]) -> int:
    import rclpy
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters, SetParameters
    from rclpy.parameter import Parameter

    rclpy.init(args=list(HELPER_ROS_ARGS))
    node = rclpy.create_node(f"fleet_param_{__import__('os').getpid()}")
    try:
        if argv[0] == "list":
            _list(node, argv[1:])
            return 0
        op, fqn, name = argv[0], argv[1], argv[2]
        got = _call(node, GetParameters, f"{fqn}/get_parameters", GetParameters.Request(names=[name]))
        current = got.values[0] if got.values else None
        if current is None or current.type == ParameterType.PARAMETER_NOT_SET:
            _reply(False, reason=f"node {fqn} has no parameter {name!r}{_closest(node, fqn, name)}", code="not_found")
            return 0
        if op == "get":
            _reply(True, _python_value(current))
            return 0
        value = _coerce(json.loads(sys.stdin.read()), current.type)  # any size: not an argument
        try:
            message = Parameter(name, value=value).to_parameter_msg()
        except Exception as error:
            _reply(False, reason=f"value {value!r} cannot be a ROS parameter: {error}", code=_refused())
            return 0
        result = _call(node, SetParameters, f"{fqn}/set_parameters", SetParameters.Request(parameters=[message]))
        outcome = result.results[0]
        if outcome.successful:
            _reply(True, value)
        elif message.value.type != current.type:  # rclpy's reason names its enum: `expected 'Type.BOOL' got ...`
            _reply(False, value, _type_mismatch(current.type, message.value.type), code=_refused())
        else:
            _reply(False, value, outcome.reason or "refused by the node", code=_refused())
        return 0
    except TimeoutError as error:
        _reply(False, reason=str(error))
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
