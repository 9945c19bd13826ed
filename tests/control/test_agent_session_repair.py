"""An agent replaces a Zenoh session that has stalled: the router is connected, but its
desired-state queries get no answer (Zenoh sometimes leaves a reconnected client so, see
fleet.server.agent).  The session is faked here: what is tested is the agent's judgement of
silence, which a real stall cannot be summoned to show on demand."""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import pytest

from fleet.server import agent as agent_module
from fleet.testing.poll import poll
from fleet.wire import protocol as p


@dataclass
class Sample:
    key_expr: str
    payload: Any


@dataclass
class Payload:
    data: bytes

    def to_bytes(self) -> bytes:
        return self.data


@dataclass
class Reply:
    ok: Sample | None
    err: Any = None


@dataclass
class Liveliness:
    tokens: list[str]

    def declare_token(self, key: str):
        self.tokens.append(key)
        return self


@dataclass
class FakeSession:
    """Answers desired-state queries as the router does (`answers`), or not at all."""

    answers: bool
    router_connected: bool = True
    queries: int = 0
    closed: bool = False
    queryables: list[str] = field(default_factory=list)
    tokens: list[str] = field(default_factory=list)

    def declare_queryable(self, key: str, handler) -> str:
        self.queryables.append(key)
        return key

    def liveliness(self) -> Liveliness:
        return Liveliness(self.tokens)

    def get(self, key: str, **options) -> list[Reply]:
        self.queries += 1
        if not self.answers:
            return []  # what a stalled session gives: nothing, at once
        return [Reply(Sample(key, Payload(p.encode(p.DesiredDone(sent=0)))))]

    @property
    def info(self):
        return self

    def routers_zid(self) -> list[str]:
        return ["router"] if self.router_connected else []

    def close(self) -> None:
        self.closed = True


@pytest.fixture
def serving(tmp_path, monkeypatch):
    """Start an agent's serving loop on a given first session; yields (agent, new sessions)."""
    monkeypatch.setattr(agent_module, "DESIRED_POLL", 0.05)
    opened: list[FakeSession] = []

    def open_new(*args, **kwargs) -> FakeSession:
        opened.append(FakeSession(answers=True))
        return opened[-1]

    monkeypatch.setattr(agent_module, "open_client_retrying", open_new)
    threads = []

    def start(first: FakeSession) -> agent_module.Agent:
        agent = agent_module.Agent("rack_a", ["tcp/127.0.0.1:0"], tmp_path / "state", address="127.0.0.1")
        agent._session = first  # type: ignore[assignment]  # a stand-in session
        agent._declare(first)
        thread = threading.Thread(target=agent._serve, daemon=True)
        thread.start()
        threads.append((agent, thread))
        return agent

    yield start, opened
    for agent, thread in threads:
        agent.stop_event.set()
        thread.join(timeout=10)
        assert not thread.is_alive()


def test_a_session_the_router_stops_answering_is_replaced(serving):
    start, opened = serving
    stalled = FakeSession(answers=False)
    agent = start(stalled)
    poll(lambda: opened, until=bool, timeout=10, what="a new session")
    assert stalled.closed and stalled.queries == agent_module.STALLED_FETCHES
    fresh = opened[0]
    assert agent._session is fresh
    assert sorted(fresh.queryables) == sorted(stalled.queryables) and len(fresh.queryables) == 6
    poll(lambda: fresh.queries, until=lambda n: n >= 5, timeout=10, what="queries on the new session")
    assert len(opened) == 1 and not fresh.closed  # it answers: kept


def test_a_session_that_is_answered_or_has_no_router_is_kept(serving):
    start, opened = serving
    answered = FakeSession(answers=True)
    alone = FakeSession(answers=False, router_connected=False)  # silence without a router says nothing
    start(answered)
    start(alone)
    poll(lambda: min(answered.queries, alone.queries), until=lambda n: n >= 5, timeout=10, what="five rounds each")
    assert opened == [] and not answered.closed and not alone.closed


def test_an_agent_says_when_its_fleet_s_discovery_host_stays_unanswered(tmp_path, monkeypatch, caplog):
    """A deploy named only the discovery host (hostA): while hostA's status gets no answer (hostA
    away, or the router's access rules deny it), the agent warns, not on every ask."""
    from fleet.server.state import FleetState

    monkeypatch.setattr(agent_module, "UNANSWERED_HOST_WARNING", 0.2)
    agent = agent_module.Agent("rack_a", ["tcp/127.0.0.1:0"], tmp_path / "state", address="127.0.0.1")
    bundle = p.BundleMessage(name="robot1", kind="robot", entry="launch.py", files={"launch.py": ""}, digest="0" * 16)
    request = p.ApplyRequest(fleet="tiny", agent="rack_a", generation=1, domain_id=1, bundles=[bundle])
    agent._fleets["tiny"] = FleetState(request=request.model_copy(update={"discovery_host": "hostA"}))
    silent = FakeSession(answers=False)
    with caplog.at_level("WARNING", logger="fleet.agent"):
        agent._find_discovery_hosts(silent)
        assert not caplog.records  # at first: it may just not be up yet
        threading.Event().wait(0.3)
        agent._find_discovery_hosts(silent)
        agent._find_discovery_hosts(silent)
    assert silent.queries == 3
    assert [r.getMessage() for r in caplog.records] == [
        "fleet tiny: agent hostA, its discovery host, has not answered for 0 s (is it running? or do the router's "
        "access rules deny this agent its status?): robots here run without the fleet's discovery server until it does"
    ]
