"""How the CLI ends when an agent refuses a request: a refusal of what the user named (an unknown
robot or node) is bad input, exit 2; the agent failing, or not answering, is a failure, exit 1.
The agent's error replies are faked (tests/control/test_control_params.py has real ones)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from fleet.client.control_client import ControlClient
from fleet.client.robots import locate_robot
from fleet.errors import EXIT_FAILURE, EXIT_USAGE, BadRequest, ControlError
from fleet.plan.view import FleetView, RobotRow
from fleet.wire import protocol as p
from tests.spec.test_bad_input import run_cli


def refusal(code: str, error: str):
    """A Zenoh reply carrying the agent's error reply."""
    payload = SimpleNamespace(to_bytes=lambda: p.error_reply(p.ProtocolError(error, code)))
    return SimpleNamespace(ok=None, err=SimpleNamespace(payload=payload))


class FakeSession:
    def __init__(self, replies):
        self.replies = replies

    def get(self, key, payload=None, timeout=None):
        return iter(self.replies)

    def close(self):
        pass


def client_answered_with(*replies) -> ControlClient:
    client = ControlClient.__new__(ControlClient)  # no Zenoh session: its replies are given
    client.connect, client.session = ["tcp/127.0.0.1:1"], FakeSession(list(replies))  # type: ignore[assignment]
    return client


@pytest.fixture
def answers(monkeypatch):
    """Every request the CLI makes of robot2's agent gets these replies."""
    holder = SimpleNamespace(replies=[])
    monkeypatch.setattr("fleet.client.connect", lambda *args: client_answered_with(*holder.replies))
    monkeypatch.setattr("fleet.client.locate_robot", lambda client, robot, fleet: ("two_robots", "local"))
    return holder


@pytest.mark.parametrize(
    "args",
    [["logs", "robot2", "nosuch"], ["param", "get", "robot2", "nosuch", "max_speed"], ["param", "list", "robot2", "x"]],
)
def test_a_node_the_robot_does_not_have_is_bad_input(answers, capsys, args):
    answers.replies = [refusal("not_found", "robot robot2 has no node 'nosuch'")]
    code, out, err = run_cli(args, capsys)
    assert (code, out) == (EXIT_USAGE, "")
    assert err == "fleet: error: <command line>: robot robot2 has no node 'nosuch'\n"


@pytest.mark.parametrize(
    "reply, message",
    [
        (refusal("agent_error", "agent error: disk full"), "agent local refused the request: agent error: disk full"),
        (refusal("not_ready", "the world has not reported"), "agent local refused the request: the world has not"),
        (None, "agent local is unreachable"),
    ],
)
def test_the_agent_failing_or_not_answering_is_a_failure(answers, capsys, reply, message):
    answers.replies = [reply] if reply else []
    code, _, err = run_cli(["logs", "robot2", "controller"], capsys)
    assert code == EXIT_FAILURE and err.startswith(f"fleet: error: {message}"), err


def test_the_refusal_codes_that_are_bad_input():
    for code in ("not_found", "invalid"):
        with pytest.raises(BadRequest) as error:
            client_answered_with(refusal(code, "no such")).logs("local", p.LogsRequest(fleet="f", robot="r"))
        assert error.value.exit_code == EXIT_USAGE and error.value.line() == "fleet: error: <command line>: no such"
    for code in ("agent_error", "wrong_agent", "malformed", "version", "too_large"):
        with pytest.raises(ControlError) as failure:
            client_answered_with(refusal(code, "no")).logs("local", p.LogsRequest(fleet="f", robot="r"))
        assert not isinstance(failure.value, BadRequest) and failure.value.exit_code == EXIT_FAILURE


def test_a_robot_nobody_deployed_is_bad_input_and_one_not_running_a_failure(monkeypatch):
    running = RobotRow(fleet="f", name="robot1", kind="robot", agent="local", state="running")
    pending = RobotRow(fleet="f", name="robot2", kind="robot", agent="hostB", state="pending")
    monkeypatch.setattr("fleet.client.robots.build_view", lambda *args: FleetView(agents=[], robots=[running, pending]))
    client = SimpleNamespace(status=lambda fleet: ([], []))
    assert locate_robot(client, "robot1", None) == ("f", "local")  # type: ignore[arg-type]
    with pytest.raises(BadRequest, match=r"no robot named 'robot9' is deployed \(robots: robot1, robot2\)$"):
        locate_robot(client, "robot9", None)  # type: ignore[arg-type]
    with pytest.raises(ControlError, match=r"robot 'robot2' is not running \(pending in fleet f\)") as failure:
        locate_robot(client, "robot2", None)  # type: ignore[arg-type]
    assert failure.value.exit_code == EXIT_FAILURE


def test_a_mistyped_robot_in_a_large_fleet_gets_the_closest_name(monkeypatch):
    rows = [RobotRow(fleet="f", name=f"rack{i:02d}", kind="robot", agent="local", state="running") for i in range(40)]
    monkeypatch.setattr("fleet.client.robots.build_view", lambda *args: FleetView(agents=[], robots=rows))
    client = SimpleNamespace(status=lambda fleet: ([], []))
    with pytest.raises(BadRequest, match=r"no robot named 'rakc07' is deployed \(did you mean 'rack07'\?\)$"):
        locate_robot(client, "rakc07", None)  # type: ignore[arg-type]
    with pytest.raises(BadRequest, match=r"no robot named 'world' is deployed$"):
        locate_robot(client, "world", None)  # type: ignore[arg-type]


def test_a_refused_apply_names_its_agent():
    """An apply holds the checked spec, not a name typed by the user: its refusal is the agent's."""
    request = p.ApplyRequest(fleet="f", agent="hostB", generation=1, domain_id=1, bundles=[])
    replies = client_answered_with(refusal("invalid", "bundles: too many")).send_applies([request])
    assert str(replies["hostB"]) == "agent hostB refused the request: bundles: too many"
    assert not isinstance(replies["hostB"], BadRequest)
