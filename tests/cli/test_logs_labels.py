"""`fleet logs ROBOT` labels each line with its node whenever the robot has several, in every
reply of a follow: a reply holding one node's new lines printed them unlabelled, among labelled
ones.  The agent's replies are given (tests/control/test_restart.py follows a real one)."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from fleet.wire import protocol as p
from tests.spec.test_bad_input import run_cli

THREE_NODES = {"controller": 10, "battery": 20, "safety": 30}


class Agent:
    """Answers the CLI's logs requests with `replies`, in turn; Ctrl-C after the last."""

    def __init__(self, replies: list[p.LogsReply]):
        self.replies = replies
        self.requests: list[p.LogsRequest] = []

    def logs(self, agent: str, request: p.LogsRequest) -> p.LogsReply:
        self.requests.append(request)
        if not self.replies:
            raise KeyboardInterrupt
        return self.replies.pop(0)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


@pytest.fixture
def agent(monkeypatch):
    holder = SimpleNamespace(agent=None)
    monkeypatch.setattr("fleet.client.connect", lambda *args: holder.agent)
    monkeypatch.setattr("fleet.client.locate_robot", lambda client, robot, fleet: ("two_robots", "local"))
    monkeypatch.setattr("time.sleep", lambda seconds: None)
    return holder


def line(node: str, text: str) -> p.LogLine:
    return p.LogLine(node=node, text=text)


def test_a_followed_robot_of_several_nodes_has_every_line_labelled(agent, capsys):
    agent.agent = Agent(
        [
            p.LogsReply(lines=[line("controller", "c1"), line("battery", "b1")], cursor=THREE_NODES),
            p.LogsReply(lines=[line("controller", "c2")], cursor=THREE_NODES),  # one node's new line
        ]
    )
    code, out, _ = run_cli(["logs", "robot1", "-f"], capsys)
    assert code in (0, None)
    assert out.splitlines() == ["[controller] c1", "[battery] b1", "[controller] c2"]


def test_a_robot_of_one_node_and_one_node_asked_for_are_not_labelled(agent, capsys):
    agent.agent = Agent([p.LogsReply(lines=[line("sleeper", "tick 1")], cursor={"sleeper": 7})])
    assert run_cli(["logs", "robot1"], capsys)[1] == "tick 1\n"
    agent.agent = Agent([p.LogsReply(lines=[line("controller", "c1")], cursor=THREE_NODES)])
    assert run_cli(["logs", "robot1", "controller"], capsys)[1] == "c1\n"
