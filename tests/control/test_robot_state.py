"""What an agent says of its robots, from their real (small, non-ROS) processes: a robot whose
node keeps exiting is `degraded` and says why, one being restarted is `pending`, and each one's
deployed generation is that of the deploy that brought what it runs."""

from __future__ import annotations

import hashlib
import re

import pytest

from fleet.server.agent import Agent
from fleet.server.units import Unit
from fleet.testing.poll import poll
from fleet.wire import protocol as p
from tests.runtime.runtime_helpers import FakePrefix

REFUSER = "#!/bin/sh\necho \"controller: error: parameter 'max_speed' = 9.0 is out of range 0.0 .. 5.0\"\nexit 2\n"
SLEEPER = "#!/bin/sh\nexec sleep 100\n"


@pytest.fixture
def prefix(tmp_path, monkeypatch) -> FakePrefix:
    prefix = FakePrefix(tmp_path / "prefix")
    prefix.add("refuser", REFUSER)
    prefix.add("sleeper", SLEEPER)
    monkeypatch.setenv("AMENT_PREFIX_PATH", str(prefix.root))  # for the agent's units
    return prefix


def bundle(name: str, nodes: str) -> p.BundleMessage:
    text = "launch:\n" + nodes
    return p.BundleMessage(
        name=name,
        kind="robot",
        entry=f"{name}.launch.yaml",
        files={f"{name}.launch.yaml": text},
        options={"isolation": "robot"},  # the embedded runner, `ros2` on PATH or not
        digest=hashlib.sha256(text.encode()).hexdigest(),
    )


def sleeper(name: str = "battery") -> str:
    return f"- node: {{pkg: demo, exec: sleeper, name: {name}}}\n"


def test_a_robot_whose_node_keeps_exiting_is_degraded_and_says_why(prefix, tmp_path):
    nodes = "- node: {pkg: demo, exec: refuser, name: controller, respawn: 'true', respawn_delay: 0.1}\n" + sleeper()
    unit = Unit("f", bundle("robot2", nodes), tmp_path / "robot2", prefix.env())
    unit.start({})
    seen: list[p.RobotState] = []

    def look() -> p.RobotState:
        seen.append(unit.state({}))
        return seen[-1]

    try:
        state = poll(
            look,
            until=lambda state: state.restarts >= 2 and state.nodes[0].state == "backoff",
            timeout=20,
            interval=0.02,
            what="the controller ended a third time",
        )
    finally:
        unit.stop()
    assert state.state == "degraded"
    assert re.fullmatch(
        r"controller exited with code 2 \(restarted \d+ times\): "
        r"controller: error: parameter 'max_speed' = 9\.0 is out of range 0\.0 \.\. 5\.0",
        state.reason,
    ), state.reason
    assert state.restarts == state.nodes[0].restarts  # the battery never ended
    ended = [look for look in seen if any(node.state == "backoff" for node in look.nodes)]
    assert ended and {look.state for look in ended} == {"degraded"}, [(look.state, look.reason) for look in ended]


@pytest.fixture
def agents(prefix, tmp_path):
    """make() -> an agent on one state directory (no Zenoh session: applied and reconciled by
    the test itself); their units are stopped at the end."""
    made: list[Agent] = []

    def make() -> Agent:
        agent = Agent("rack_a", ["tcp/127.0.0.1:0"], tmp_path / "state", address="127.0.0.1")
        agent.store.claim()
        made.append(agent)
        return agent

    yield make
    for agent in made:
        agent._stop_all_units()


def request(generation: int, *bundles: p.BundleMessage) -> p.ApplyRequest:
    return p.ApplyRequest(fleet="f", agent="rack_a", generation=generation, domain_id=0, bundles=list(bundles))


def deployed(agent: Agent) -> dict[str, tuple[int, int]]:
    """robot -> (generation, deployed_generation) as the agent's status says."""
    return {robot.name: (robot.generation, robot.deployed_generation) for robot in agent.status("f").robots}


def test_a_robot_s_deployed_generation_is_the_deploy_that_brought_what_it_runs(agents):
    agent = agents()
    robot1, robot2 = bundle("robot1", sleeper()), bundle("robot2", sleeper())
    assert agent.apply(request(1, robot1, robot2)).accepted
    agent._reconcile("f")
    assert deployed(agent) == {"robot1": (1, 1), "robot2": (1, 1)}
    assert agent.apply(request(2, robot1, bundle("robot2", sleeper("safety")))).accepted  # robot2 alone changes
    agent._reconcile("f")
    assert deployed(agent) == {"robot1": (2, 1), "robot2": (2, 2)}
    agent._stop_all_units()

    again = agents()  # the agent started again: its robots come back from its state directory
    again._restore()
    again._reconcile("f")
    assert deployed(again) == {"robot1": (2, 1), "robot2": (2, 2)}


def test_a_robot_being_restarted_is_pending_not_stopped(agents):
    agent = agents()
    assert agent.apply(request(1, bundle("robot1", sleeper()))).accepted
    agent._reconcile("f")
    assert agent.apply(request(2, bundle("robot1", sleeper("safety")))).accepted
    agent._units[("f", "robot1")].stop()  # the reconcile's first step: stop it to start it again
    (robot,) = agent.status("f").robots
    assert robot.state == "pending" and robot.reason.startswith("restarting"), robot
    assert robot.deployed_generation == 2  # what it is brought to


def test_live_overrides_outlive_a_restart_into_another_ros_environment_not_a_change(agents):
    """`fleet param set` values are kept until the robot's spec changes: a deploy that only moves
    the fleet's ROS domain (or discovery server) restarts the robot with them."""
    agent = agents()
    robot1, robot2 = bundle("robot1", sleeper()), bundle("robot2", sleeper())
    assert agent.apply(request(1, robot1, robot2)).accepted
    agent._reconcile("f")
    agent._fleets["f"].overrides = {name: {f"/{name}/battery": {"rate": 2.0}} for name in ("robot1", "robot2")}
    moved = request(2, robot1, bundle("robot2", sleeper("safety"))).model_copy(update={"domain_id": 1})
    reply = agent.apply(moved)
    assert reply.accepted and reply.changes.restart == ["robot1", "robot2"], reply
    assert agent._fleets["f"].overrides == {"robot1": {"/robot1/battery": {"rate": 2.0}}}  # robot2 changed
