"""A status query the router itself does not answer in time waits longer, and says so: for up to
10 s after an agent's cable is pulled, the router closing that agent's link answers nothing
(measured in tests/multihost; see ROUTER_STALL). A router that denies or has nothing still ends
at once. The session is faked: its replies are given, one list per query."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from fleet.client.control_client import ROUTER_STALL, STATUS_TIMEOUT, ControlClient
from fleet.client.deployment import visible_statuses
from fleet.errors import ControlError, RouterSilent
from fleet.wire import protocol as p


def ok(message: p.Message):
    return SimpleNamespace(ok=SimpleNamespace(payload=SimpleNamespace(to_bytes=lambda: p.encode(message))), err=None)


TIMEOUT = SimpleNamespace(ok=None, err=SimpleNamespace(payload=SimpleNamespace(to_bytes=lambda: b"Timeout")))
REGISTRY = ok(p.RegistryReply(fleet="two_robots"))


class ScriptedSession:
    """Answers each get with the next list of replies; remembers each get's timeout."""

    def __init__(self, *answers):
        self.answers, self.timeouts = list(answers), []

    def get(self, key, payload=None, target=None, consolidation=None, timeout=None):
        self.timeouts.append(timeout)
        return iter(self.answers.pop(0))


def scripted(*answers) -> tuple[ControlClient, ScriptedSession, list[str]]:
    said: list[str] = []
    client = ControlClient.__new__(ControlClient)  # no Zenoh session: its replies are given
    client.connect, client.zenoh_config, client.on_wait = ["tcp/127.0.0.1:1"], None, said.append
    client.session = session = ScriptedSession(*answers)  # type: ignore[assignment]
    return client, session, said


def test_a_router_late_with_its_own_answer_is_waited_for_and_that_is_said():
    client, session, said = scripted([TIMEOUT], [REGISTRY, TIMEOUT])
    statuses, registries = client.status()
    assert [registry.fleet for registry in registries] == ["two_robots"] and statuses == []
    assert session.timeouts == [STATUS_TIMEOUT, ROUTER_STALL]
    assert len(said) == 1 and "has not answered for 3 s" in said[0] and "12 s more" in said[0]


def test_an_agent_that_does_not_answer_is_not_waited_for_longer():
    """The registry came: the timeout was a silent agent's (shown as unreachable), not the router's."""
    client, session, said = scripted([REGISTRY, TIMEOUT])
    assert len(client.status()[1]) == 1
    assert session.timeouts == [STATUS_TIMEOUT] and said == []


def test_a_query_that_ends_without_the_router_fails_at_once():
    """Denied (an agent's credentials) or nothing known: the query ends, and no wait would help."""
    client, session, said = scripted([], [])
    with pytest.raises(ControlError, match="did not answer the status query"):
        client.status()
    assert session.timeouts == [STATUS_TIMEOUT, STATUS_TIMEOUT] and said == []


def test_a_router_silent_even_then_is_an_error():
    client, session, said = scripted([TIMEOUT], [TIMEOUT], [])
    with pytest.raises(RouterSilent, match="did not answer the status query in 15 s"):
        client.status()
    assert session.timeouts == [STATUS_TIMEOUT, ROUTER_STALL, STATUS_TIMEOUT] and len(said) == 1


def test_the_fleet_alone_is_asked_after_a_denial_not_after_silence():
    """deploy and diff check every fleet's domain, or their own fleet's where the router denies
    the wildcard: a router silent for the wildcard would be as silent for the fleet, and waited
    for twice."""
    fleet = ok(p.RegistryReply(fleet="tiny"))
    client, session, _ = scripted([], [], [fleet])  # denied, nothing for NO_FLEET, then the fleet's
    assert [registry.fleet for registry in visible_statuses(client, "tiny")[1]] == ["tiny"]
    assert len(session.timeouts) == 3
    client, session, _ = scripted([TIMEOUT], [TIMEOUT], [])
    with pytest.raises(RouterSilent):
        visible_statuses(client, "tiny")
    assert session.timeouts == [STATUS_TIMEOUT, ROUTER_STALL, STATUS_TIMEOUT]


def test_a_connection_the_router_does_not_take_is_waited_for_and_that_is_said(monkeypatch):
    """A real Zenoh client against a listener that takes the TCP connection and never answers (as
    a router busy closing a dead link): the note comes while it waits, then the usual error."""
    import socket

    monkeypatch.setattr("fleet.client.control_client.OPEN_NOTE_AFTER", 1.0)
    monkeypatch.setattr("fleet.client.control_client.OPEN_TIMEOUT_MS", 2500)
    said: list[str] = []
    with socket.socket() as mute:
        mute.bind(("127.0.0.1", 0))
        mute.listen()
        endpoint = f"tcp/127.0.0.1:{mute.getsockname()[1]}"
        with pytest.raises(ControlError, match="cannot reach the fleet router"):
            ControlClient([endpoint], on_wait=said.append)
    assert said == [
        f"the fleet router at {endpoint} has not taken the connection in 1 s (closing the link of an agent that "
        "just went away?); waiting up to 2 s"
    ]
