"""`fleet param get/set/list` with the fleet faked: how values are typed, shown and refused.
(tests/control/test_control_params.py runs them against real nodes.)"""

from __future__ import annotations

import pytest

from fleet.expand.parameters import parse_override
from fleet.wire import protocol as p
from tests.spec.test_bad_input import run_cli


class FakeFleet:
    """A router with one agent running robot1, whose nodes answer with `reply` (a ParamReply, or
    the same value that was set)."""

    def __init__(self, reply: p.ParamReply | None = None):
        self.reply = reply
        self.requests: list[p.ParamRequest] = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        pass

    def param(self, agent: str, request: p.ParamRequest) -> p.ParamReply:
        self.requests.append(request)
        return self.reply or p.ParamReply(ok=True, value=request.value)


@pytest.fixture
def fleet(monkeypatch):
    fake = FakeFleet()
    monkeypatch.setattr("fleet.client.connect", lambda *args: fake)
    monkeypatch.setattr("fleet.client.locate_robot", lambda client, robot, fleet: ("two_robots", "local"))
    return fake


@pytest.mark.parametrize("text", ["1e-1", "5.", "1_000", "no", "On", "0x1f", "[1.0, 2e0]", "", "hello"])
def test_set_types_its_value_as_set_does(fleet, capsys, text):
    code, _, stderr = run_cli(["param", "set", "robot1", "controller", "max_speed", text], capsys)
    assert code == 0, stderr
    sent = fleet.requests[-1].value
    expected = parse_override(f"robot1.controller.max_speed={text}").value
    assert sent == expected and type(sent) is type(expected), (text, sent, expected)


def test_a_double_written_with_an_exponent_is_sent_as_a_double(fleet, capsys):
    code, out, _ = run_cli(["param", "set", "robot1", "controller", "max_speed", "1e-1"], capsys)
    assert code == 0 and fleet.requests[-1].value == 0.1 and isinstance(fleet.requests[-1].value, float)
    assert out == "robot1/controller: max_speed = 0.1 (recorded on the agent)\n"


def test_values_are_printed_as_ros_yaml_writes_them(fleet, capsys):
    """As `param list` and `ros2 param dump` show them: true, not Python's True."""
    shown_as: list[tuple[p.ParamValue, str]] = [
        (False, "false"),
        (0.5, "0.5"),
        ("true", "'true'"),
        ([1.0, 2.0], "[1.0, 2.0]"),
    ]
    for value, shown in shown_as:
        fleet.reply = p.ParamReply(ok=True, value=value)
        code, out, _ = run_cli(["param", "get", "robot1", "controller", "loop"], capsys)
        assert (code, out) == (0, f"{shown}\n")
    fleet.reply = None
    code, out, _ = run_cli(["param", "set", "robot1", "controller", "loop", "no"], capsys)
    assert (code, out) == (0, "robot1/controller: loop = false (recorded on the agent)\n")
    fleet.reply = p.ParamReply(ok=True, parameters={"controller": {"loop": True, "frame": "no"}})
    code, out, _ = run_cli(["param", "list", "robot1"], capsys)
    rows = {line.split()[1]: line.split()[2] for line in out.splitlines() if line.startswith("controller")}
    assert code == 0 and rows == {"loop": "true", "frame": "'no'"}, out


def test_an_empty_value_is_an_empty_string_and_a_refusal_shows_it(fleet, capsys):
    fleet.reply = p.ParamReply(
        ok=False, reason="Wrong parameter type, expected 'Type.DOUBLE' got 'Type.STRING'", code=p.REFUSED
    )
    code, _, stderr = run_cli(["param", "set", "robot1", "controller", "max_speed", ""], capsys)
    assert fleet.requests[-1].value == ""
    assert code == 2 and stderr == (
        "fleet: error: robot1/controller refused max_speed='': "
        "Wrong parameter type, expected 'Type.DOUBLE' got 'Type.STRING'\n"
    )


def test_a_set_the_node_did_not_answer_is_no_refusal(fleet, capsys):
    """`refused` is a node's answer; a node that is not running (or did not answer) refused nothing."""
    reason = "robot1/controller is not running (backoff: controller exited with code 2 (restarted 3 times))"
    fleet.reply = p.ParamReply(ok=False, reason=reason)
    code, out, stderr = run_cli(["param", "set", "robot1", "controller", "max_speed", "0.5"], capsys)
    assert (code, out, stderr) == (1, "", f"fleet: error: {reason}\n")


@pytest.mark.parametrize(
    "args, problem",
    [
        (["get", "robot1", "controller", ""], "a get needs a node and a parameter name"),
        (["set", "robot1", "", "max_speed", "1"], "a set needs a node and a parameter name"),
        (["get", "robot1", "controller", "max speed"], "name: String should match pattern"),
    ],
)
def test_a_request_that_names_no_parameter_is_one_clean_line(monkeypatch, capsys, args, problem):
    def no_connection(*args, **kwargs):
        raise AssertionError("bad input must be refused before connecting")

    monkeypatch.setattr("fleet.client.connect", no_connection)
    code, out, err = run_cli(["param", *args], capsys)
    assert (code, out) == (2, "")
    assert err.startswith(f"fleet: error: <command line>: invalid parameter request: {problem}"), err
    assert err.count("\n") == 1 and "Value error" not in err


def test_list_of_a_node_that_does_not_answer_is_its_error_alone(fleet, capsys):
    """No empty table above the error: the one node asked for did not answer."""
    fleet.reply = p.ParamReply(ok=True, unanswered={"controller": "it has no parameter services (not running)"})
    code, out, stderr = run_cli(["param", "list", "robot1", "controller"], capsys)
    assert (code, out) == (1, "")
    assert stderr == "fleet: error: robot1/controller: it has no parameter services (not running)\n"
    fleet.reply = p.ParamReply(ok=True, parameters={"battery": {"capacity": 50.0}}, unanswered={"controller": "gone"})
    code, out, stderr = run_cli(["param", "list", "robot1"], capsys)
    assert code == 1 and "capacity" in out and stderr == "fleet: error: robot1/controller: gone\n"


def test_list_says_once_why_the_nodes_of_a_process_that_is_not_running_did_not_answer(fleet, capsys):
    """A robot's hosted (or composed) nodes stop together, for one reason: one line for them."""
    why = "not running (backoff: its hosted nodes stopped (restarted 8 times): /robot1/controller: no)"
    fleet.reply = p.ParamReply(ok=True, unanswered={"controller": why, "battery": why, "safety": "gone"})
    code, out, stderr = run_cli(["param", "list", "robot1"], capsys)
    assert (code, out) == (1, "")
    assert stderr == f"fleet: error: robot1/controller+battery: {why}\nfleet: error: robot1/safety: gone\n"
