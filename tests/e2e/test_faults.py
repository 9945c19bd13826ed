"""Faults, each followed by a check that the fleet is back to its desired state and that no
process leaked.  fleets/two_robots.yaml on two agents (hostA: the world and robot1, hostB:
robot2), so an agent's fault hits part of the fleet while the rest keeps running."""

from __future__ import annotations

import os
import signal
import time

import psutil
import pytest

from fleet.testing import Pose, running_fleet
from tests.e2e.e2e_helpers import TWO_ROBOTS, RouteProgress, node_pids, spec_with, wait_driving

pytestmark = pytest.mark.integration

ROBOTS = ("robot1", "robot2")


def on_two_agents(data) -> None:
    data["agents"] = {"hostA": {"description": "world and robot1"}, "hostB": {"description": "robot2"}}
    data["defaults"]["agent"] = "hostA"
    data["world"]["agent"] = "hostA"
    next(robot for robot in data["robots"] if robot["name"] == "robot2")["agent"] = "hostB"


@pytest.fixture(scope="module")
def spec(tmp_path_factory):
    return spec_with(TWO_ROBOTS, tmp_path_factory.mktemp("spec"), on_two_agents)


@pytest.fixture(scope="module")
def two_agents(tmp_path_factory, spec):
    with running_fleet(spec, directory=tmp_path_factory.mktemp("faults")) as fleet:
        yield fleet


@pytest.fixture
def fleet(two_agents, spec):
    """The module's fleet running its spec, whatever an earlier (maybe failed) test left."""
    two_agents.start_missing()
    two_agents.deploy(spec, sets=[])
    two_agents.wait_desired_state()
    wait_driving(two_agents, ROBOTS)
    return two_agents


def drives_on(fleet, robot: str, distance: float = 0.3, sim_timeout: float = 10.0) -> None:
    start = fleet.pose(robot)
    fleet.wait_for(
        lambda: fleet.pose(robot).distance_to(start) > distance,
        sim_timeout=sim_timeout,
        what=f"{robot} to drive {distance} m",
    )


def test_killed_node_is_respawned(fleet):
    old = fleet.kill_node("robot1", "controller")
    fleet.wait_desired_state(timeout=30)
    controller = next(node for node in fleet.robot_status("robot1").nodes if node["name"] == "controller")
    assert controller["pid"] != old and controller["restarts"] >= 1
    drives_on(fleet, "robot1")
    fleet.assert_no_leaks()


def test_a_restarted_robot_on_another_agent_runs_again_and_drives_on(fleet):
    """fleet.restart: robot2's nodes on hostB stop and start again (all new processes), robot1's
    on hostA are not touched, and robot2 drives on in the world."""
    before = {robot: fleet.pids(robot) for robot in ROBOTS}
    outcome = fleet.restart("robot2")
    assert outcome.ok and outcome.asked[("two_robots", "robot2")][0] == "hostB", outcome.to_json()
    assert not fleet.pids("robot2") & before["robot2"] and fleet.pids("robot1") == before["robot1"]
    drives_on(fleet, "robot2")
    fleet.assert_no_leaks()


def test_killed_agent_restores_its_robots_from_persisted_state(fleet):
    before = node_pids(fleet.status())
    generation = fleet.robot_status("robot2").generation
    fleet.kill_agent("hostB")
    fleet.wait_for(lambda: fleet.robot_status("robot2").state == "offline", timeout=5, what="robot2 shown offline")
    fleet.wait_for(
        lambda: not any(psutil.pid_exists(pid) for pid in before["robot2"]),
        timeout=5,
        what="robot2's nodes to die with their agent",
    )

    fleet.start_agent("hostB")  # same state directory, no deploy: it restores what it had accepted
    after = node_pids(fleet.wait_desired_state(timeout=60))
    assert fleet.robot_status("robot2").generation == generation
    assert after["robot2"].isdisjoint(before["robot2"])
    assert after["robot1"] == before["robot1"] and after["world"] == before["world"]
    drives_on(fleet, "robot2")
    fleet.assert_no_leaks()


def test_killed_world_restarts_with_robots_at_their_last_poses(fleet):
    spawn = {robot: Pose(fleet.spec.robot(robot).pose.x, fleet.spec.robot(robot).pose.y, 0.0) for robot in ROBOTS}
    fleet.wait_for(
        lambda: all(fleet.pose(r).distance_to(spawn[r]) > 0.5 for r in ROBOTS),
        sim_timeout=20,
        what="both robots 0.5 m away from their spawn poses",
    )
    robots_before = {robot: fleet.pids(robot) for robot in ROBOTS}
    killed_at = time.time()
    fleet.kill_world()
    last = {robot: fleet.pose(robot) for robot in ROBOTS}  # the dead world's last status file
    last_time = fleet.world()["sim_time"]

    # The respawned world's first status: its clock went on from the old one's (not back to 0),
    # and each robot is where the old world left it (it may have driven since, at most 1 m/s
    # times the sim time that passed).
    first = fleet.wait_for(
        lambda: (world := fleet.world()) and world["wall_time"] > killed_at and world,
        timeout=30,
        what="a status from the restarted world",
    )
    assert first["sim_time"] > last_time, (last_time, first["sim_time"])
    for robot in ROBOTS:
        pose = first["robots"][robot]["pose"]
        moved = last[robot].distance_to((pose["x"], pose["y"]))
        elapsed = first["sim_time"] - last_time
        assert moved <= 1.0 * elapsed + 0.05, (robot, last[robot], pose, elapsed)

    fleet.wait_desired_state(timeout=30)
    assert {robot: fleet.pids(robot) for robot in ROBOTS} == robots_before  # the robots' nodes kept running
    for robot in ROBOTS:  # and they patrol on, on the new world's clock
        route = RouteProgress(fleet, robot)
        fleet.wait_for(
            lambda route=route: route.update() >= 2, sim_timeout=30, what=f"{robot} to reach two more waypoints"
        )
    fleet.assert_no_leaks()


def test_a_deploy_restarting_a_robot_is_up_only_once_its_new_nodes_reach_the_world(fleet):
    """For a few seconds the world remembers the last command of the robot's previous processes:
    that must not pass for the new ones' data (the deploy had said `fleet up` on it)."""
    before = fleet.pids("robot1")
    fleet.deploy(sets=["robot1.controller.max_speed=0.35"])  # restarts robot1; fails the test unless ok
    world = fleet.world()  # read once the deploy has said every robot runs
    after = fleet.pids("robot1")
    assert world is not None and after and after.isdisjoint(before)
    started = min(psutil.Process(pid).create_time() for pid in after)
    cmd_age = world["robots"]["robot1"]["cmd_age"]
    assert cmd_age is not None, "the world has no command from robot1"
    heard = world["wall_time"] - cmd_age
    assert heard > started, f"the world last heard robot1 {started - heard:.2f} s before its new nodes started"


def test_killed_world_agent_comes_back_and_the_robots_of_the_other_agent_drive_on(fleet):
    """hostA runs the world and the fleet's DDS discovery server; robot2's nodes on hostB outlive
    its SIGKILL.  The restarted agent's new world must find them: its new server must be one
    robot2's nodes announce themselves to (they had taken one started at once for the old one,
    and were cut off from the world for good)."""
    robot2 = fleet.pids("robot2")
    fleet.restart_agent("hostA", signal.SIGKILL)
    fleet.wait_desired_state(timeout=60)
    assert fleet.pids("robot2") == robot2  # the same nodes, not restarted
    for robot in ROBOTS:
        drives_on(fleet, robot)
    fleet.assert_no_leaks()


def test_a_participant_started_after_the_discovery_server_was_killed_finds_the_others(fleet):
    """The discovery server alone is SIGKILLed; its agent starts it again.  A world started after
    that (a new participant) must still find every robot's nodes, which knew the old server."""
    (server,) = fleet.status().discovery[fleet.name]
    os.kill(server["pid"], signal.SIGKILL)

    def restarted():
        (now,) = fleet.status().discovery[fleet.name]
        return now["pid"] not in (None, server["pid"])

    fleet.wait_for(restarted, timeout=30, what="the discovery server to run again")
    fleet.restart("world")
    fleet.wait_desired_state(timeout=30)
    for robot in ROBOTS:
        drives_on(fleet, robot)
    fleet.assert_no_leaks()


def test_router_restart_agents_reconnect(fleet):
    before = node_pids(fleet.status())
    fleet.kill_router(signal.SIGKILL)
    fleet.wait_sim(1.0)  # robots keep running without the control plane
    assert all(psutil.pid_exists(pid) for pids in before.values() for pid in pids)

    fleet.start_router()

    def back():
        view = fleet.status()
        online = {agent.name for agent in view.agents if agent.online}
        return online == {"hostA", "hostB"} and view.all_running and len(view.robots) == 3 and view

    # How fast agents reconnect is measured in tests/control/test_control_router_restart.py (from
    # the moment the router listens, not from its process start, which a loaded machine slows).
    view = fleet.wait_for(back, timeout=15, what="both agents to answer status through the new router")
    assert node_pids(view) == before
    fleet.wait_desired_state(timeout=10)
    fleet.assert_no_leaks()


def test_deploy_while_an_agent_is_down_is_reported_then_completed(fleet):
    sets = ["robot1.controller.max_speed=0.5", "robot2.controller.max_speed=0.6"]
    fleet.kill_agent("hostB")
    outcome = fleet.deploy(sets=sets, check=False, timeout=30)
    assert not outcome.ok and set(outcome.unreachable) == {"hostB"}
    rows = {row.name: row for row in fleet.status().robots}
    assert rows["robot1"].state == "running" and rows["robot1"].generation == outcome.generation
    assert rows["robot2"].state == "offline"
    assert fleet.get_param("robot1", "controller", "max_speed") == 0.5

    robot1_pids = fleet.pids("robot1")

    # hostB comes back and completes the deploy by itself (it fetches the desired state the router
    # kept for it): no second deploy, and hostA is left alone.
    fleet.start_agent("hostB")
    fleet.wait_for(
        lambda: (row := fleet.robot_status("robot2")).state == "running" and row.generation == outcome.generation,
        timeout=60,
        what="robot2 at the deploy's generation",
    )
    fleet.wait_desired_state()
    assert fleet.robot_status("robot2").generation == outcome.generation
    assert fleet.pids("robot1") == robot1_pids
    assert fleet.get_param("robot2", "controller", "max_speed") == 0.6
    fleet.assert_no_leaks()


def shared_memory_of(pids) -> list[str]:
    """Fast DDS shared-memory files (/dev/shm) that any of `pids` has mapped."""
    found = []
    for pid in pids:
        try:
            maps = psutil.Process(pid).memory_maps(grouped=True)
        except psutil.Error:
            continue
        found += [f"pid {pid}: {m.path}" for m in maps if m.path.startswith("/dev/shm/") and "fastrtps" in m.path]
    return found


def test_nodes_killed_many_times_leave_no_shared_memory_to_poison_dds(fleet):
    """Fast DDS segments left in /dev/shm by SIGKILLed participants were seen to hang every new
    participant of their domain.  The fleet's processes must not use shared memory at all, so
    killing them can leave nothing behind; and after many kills a deploy and a probe work."""
    for round_ in range(6):
        fleet.kill_node(("robot1", "robot2")[round_ % 2], ("controller", "battery", "safety")[round_ % 3])
        view = fleet.wait_desired_state(timeout=60)  # respawned: the next kill finds it running
    pids = {pid for row in view.robots for pid in row.pids} | view.service_pids
    assert pids and not shared_memory_of(pids)
    fleet.deploy(sets=["robot1.controller.max_speed=0.3"])  # restarts robot1: new participants
    fleet.wait_desired_state(timeout=60)
    assert fleet.get_param("robot1", "controller", "max_speed") == 0.3
    drives_on(fleet, "robot1")
    fleet.assert_no_leaks()


@pytest.mark.soak
def test_fleet_survives_repeated_faults(fleet):
    """Every fault five times over, the fleet back to its desired state after each, robots still
    patrolling without touching each other, nothing leaked."""
    for round_ in range(5):
        fleet.kill_node("robot2", ["controller", "battery", "safety"][round_ % 3])
        fleet.wait_desired_state(timeout=30)
        fleet.restart_agent("hostB")
        fleet.wait_desired_state(timeout=60)
        fleet.kill_world()
        fleet.wait_desired_state(timeout=30)
        fleet.restart_router(signal.SIGKILL if round_ % 2 else signal.SIGTERM)
        fleet.wait_desired_state(timeout=30)
        fleet.restart_agent("hostA", signal.SIGKILL if round_ % 2 else signal.SIGTERM)
        fleet.wait_desired_state(timeout=60)
        for robot in ROBOTS:
            drives_on(fleet, robot)
        fleet.assert_no_leaks()
    assert not [c for c in fleet.contacts() if {c["a"], c["b"]} == set(ROBOTS)]
