"""Pure tests of the no-op redeploy check: a deploy sends nothing only when every agent it would
send to already holds exactly that content, at one generation, and no other agent serves the fleet."""

from __future__ import annotations

from fleet.plan import held_generation
from fleet.wire import protocol as p


def bundle(name: str, digest: str = "ab" * 32, params: str = "x: 1\n") -> p.BundleMessage:
    files = {"robot.launch.yaml": "launch: []\n", "robot.params.yaml": params}
    return p.BundleMessage(
        name=name, kind="robot", entry="robot.launch.yaml", files=files, hot_files=["robot.params.yaml"], digest=digest
    )


def request(agent: str, *bundles: p.BundleMessage, generation: int = 7, **fields) -> p.ApplyRequest:
    return p.ApplyRequest(
        fleet="f", agent=agent, generation=generation, domain_id=3, bundles=list(bundles), sent_at=1.0, **fields
    )


def holding(held: p.ApplyRequest, fleet: str = "f") -> p.StatusReply:
    info = p.AgentInfo(name=held.agent, hostname=held.agent, cores=2, pid=1, version="0", started_at=0.0)
    return p.StatusReply(
        agent=info, fleet=fleet, time=0.0, generation=held.generation, content_digest=held.content_digest()
    )


WANTED = [request("a", bundle("r1"), bundle("r2")), request("b", bundle("r3"))]


def test_agents_holding_the_same_content_need_nothing_sent():
    # Held from an earlier deploy: another generation number and send time, the same content.
    earlier = [request("a", bundle("r1"), bundle("r2"), generation=5), request("b", bundle("r3"), generation=5)]
    for held in earlier:
        held.sent_at = 0.5
    assert held_generation(WANTED, [holding(held) for held in earlier]) == 5


def test_any_difference_means_sending():
    cases = {
        "a robot changed": request("b", bundle("r3", digest="cd" * 32), generation=5),
        "a hot file changed": request("b", bundle("r3", params="x: 2\n"), generation=5),
        "another domain": request("b", bundle("r3"), generation=5).model_copy(update={"domain_id": 4}),
        "another transport": request("b", bundle("r3"), generation=5, transport="zenoh"),
        "a robot more": request("b", bundle("r3"), bundle("r4"), generation=5),
        "another discovery server": request("b", bundle("r3"), generation=5, discovery_server="10.0.0.1:11811"),
    }
    agent_a = holding(request("a", bundle("r1"), bundle("r2"), generation=5))
    for what, held_by_b in cases.items():
        assert held_generation(WANTED, [agent_a, holding(held_by_b)]) is None, what


def test_a_missing_or_extra_or_out_of_step_agent_means_sending():
    a5, b5 = request("a", bundle("r1"), bundle("r2"), generation=5), request("b", bundle("r3"), generation=5)
    assert held_generation(WANTED, [holding(a5)]) is None  # b did not answer (or holds nothing)
    assert held_generation(WANTED, [holding(a5), holding(b5), holding(request("c", bundle("r9")))]) is None
    b6 = request("b", bundle("r3"), generation=6)
    assert held_generation(WANTED, [holding(a5), holding(b6)]) is None
    other_fleet = holding(b5, fleet="g")
    assert held_generation(WANTED, [holding(a5), other_fleet]) is None
    no_digest = holding(b5).model_copy(update={"content_digest": ""})  # an agent of an older fleet version
    assert held_generation(WANTED, [holding(a5), no_digest]) is None
    assert held_generation([], []) is None
