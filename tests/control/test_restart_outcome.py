"""When `fleet restart` counts a robot as started again: its agent's count of restarts reaches
the number the agent answered, or the agent itself was started again since (a new agent process
starts its robots anew and counts from 0, so the number asked for would never come).

A stand-in agent plays the status and the restart reply; the waiting is fleet's own code.
"""

from __future__ import annotations

import time
from typing import Any, cast

from fleet.client import ControlClient, Restart
from fleet.client import restart as restart_robots
from fleet.wire import protocol as p


class RestartingAgent:
    """Agent hostA runs robot1; it answers a restart with the next number and when its process
    started, and then reports what the test sets: how many restarts it carried out, and when its
    process started."""

    def __init__(self) -> None:
        self.started_at = 1000.0
        self.restarted = 2  # carried out before this one
        self.asked: list[p.RestartRequest] = []

    def status(self, fleet=None, timeout=3.0):
        node = p.NodeState(name="controller", state="running", pid=42, uptime=30.0)
        robot = p.RobotState(
            name="robot1", state="running", nodes=[node], running=1, total=1, generation=7, restarted=self.restarted
        )
        status = p.StatusReply(
            agent=p.AgentInfo(name="hostA", hostname="a", cores=2, pid=1, version="0", started_at=self.started_at),
            fleet="tiny",
            generation=7,
            reconciled_generation=7,
            domain_id=0,
            robots=[robot],
            time=time.time(),
        )
        plan = p.PlanRecord(fleet="tiny", generation=7, robots={"robot1": "hostA"}, deployed_at=0.0)
        return [status], [p.RegistryReply(fleet="tiny", plan=plan, history=[plan])]

    def restart(self, agent, request):
        self.asked.append(request)
        return p.RestartReply(restart=self.restarted + 1, agent_started_at=self.started_at)


def restart(agent: RestartingAgent, robots: list[str], **options: Any) -> Restart:
    return restart_robots(cast(ControlClient, agent), robots, **options)


def test_a_robot_counts_as_back_once_its_agent_carried_out_the_restart_asked():
    agent = RestartingAgent()

    def carried_out(_rows) -> None:
        agent.restarted = 3

    outcome = restart(agent, ["robot1"], timeout=2.0, on_progress=carried_out)
    assert agent.asked == [p.RestartRequest(fleet="tiny", robot="robot1")]
    assert outcome.asked == {("tiny", "robot1"): ("hostA", 3)}
    assert outcome.ok and not outcome.timed_out


def test_a_robot_whose_agent_has_not_restarted_it_yet_is_not_back():
    agent = RestartingAgent()  # still at 2 restarts, the same agent process
    outcome = restart(agent, ["robot1"], timeout=0.5)
    assert outcome.timed_out and not outcome.ok
    assert outcome.restarted(("tiny", "robot1")) is None


def test_a_robot_whose_agent_was_started_again_since_is_back_though_the_count_began_anew():
    agent = RestartingAgent()

    def agent_restarts(_rows) -> None:  # after the restart was asked: a new agent process, counting from 0
        agent.started_at, agent.restarted = 2000.0, 0

    outcome = restart(agent, ["robot1"], timeout=2.0, on_progress=agent_restarts)
    assert not outcome.timed_out
    assert outcome.ok


def test_an_agent_started_again_before_it_answered_is_waited_for_by_its_own_count():
    """The status before the request shows the old agent process; the new one answered (its
    number 1): the robot is back only once that one has carried out the restart."""
    agent = RestartingAgent()
    first = agent.status

    def old_agent_first(fleet=None, timeout=3.0):  # the status taken before the request
        shown = first(fleet, timeout)
        agent.started_at, agent.restarted = 2000.0, 0  # then the agent restarts, before the request
        agent.status = first  # type: ignore[method-assign]
        return shown

    agent.status = old_agent_first  # type: ignore[method-assign]
    polls: list[int] = []

    def carried_out_later(_rows) -> None:
        polls.append(agent.restarted)
        if len(polls) == 3:
            agent.restarted = 1

    outcome = restart(agent, ["robot1"], timeout=5.0, on_progress=carried_out_later)
    assert outcome.asked == {("tiny", "robot1"): ("hostA", 1)}
    assert outcome.ok and polls == [0, 0, 0, 1], polls
