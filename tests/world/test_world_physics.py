"""pybullet world without ROS: contacts, no pass-through, walls stop robots, spawn refusal."""

import pytest

from fleet.world.description import ModelSpec, ObstacleSpec, Pose2D
from fleet.world.physics import PhysicsWorld, SpawnError

LIGHT = ModelSpec()


@pytest.fixture
def world():
    w = PhysicsWorld(240.0)
    yield w
    w.close()


def run(world, seconds):
    events = []
    for _ in range(round(seconds / world.dt)):
        world.step()
        events += world.poll_contacts()
    return events


def test_robot_driven_into_another_reports_one_contact_and_does_not_pass(world):
    world.add_robot("a", LIGHT, Pose2D(0, 0, 0))
    world.add_robot("b", LIGHT, Pose2D(1.0, 0, 0))
    world.command("a", 1.0, 0.0)
    events = []
    for _ in range(2 * 240):
        world.step()
        events += world.poll_contacts()
        assert world.state("b").x - world.state("a").x > 0.38  # radii 0.2 + 0.2, a little give
    assert [(e.a, e.b, e.kind) for e in events] == [("a", "b", "robot-robot")]  # once, not every tick
    assert 0.5 < events[0].sim_time < 0.75  # 0.6 m gap at 1 m/s


def test_robot_driven_into_wall_stops_at_it(world):
    world.add_obstacle(ObstacleSpec("wall", "box", 2.0, 0.0, 0.0, size=(0.2, 4.0, 1.0), height=1.0))
    world.add_robot("a", LIGHT, Pose2D(0, 0, 0))
    world.command("a", 1.0, 0.0)
    events = run(world, 4.0)
    state = world.state("a")
    assert 1.65 < state.x <= 1.71  # wall face at 1.9, radius 0.2
    assert abs(state.linear) < 0.05
    assert [(e.a, e.b, e.kind) for e in events] == [("a", "wall", "robot-obstacle")]


def test_light_robot_stays_flat_and_turns(world):
    world.add_robot("a", LIGHT, Pose2D(0, 0, 0))
    world.command("a", 0.5, 1.0)
    run(world, 1.0)
    state = world.state("a")
    assert abs(state.yaw - 1.0) < 0.02 and abs(state.linear - 0.5) < 0.01
    world.command("a", 9.0, 0.0)  # clamped to max_linear_speed
    run(world, 0.1)
    assert abs(world.state("a").linear - LIGHT.max_linear_speed) < 1e-6


def test_spawn_refused_on_overlap(world):
    world.add_obstacle(ObstacleSpec("pillar", "cylinder", 2.0, 2.0, radius=0.3, height=1.0))
    world.add_robot("a", LIGHT, Pose2D(0, 0, 0))
    with pytest.raises(SpawnError, match="overlaps obstacle 'pillar'"):
        world.add_robot("b", LIGHT, Pose2D(2.3, 2.0, 0))
    with pytest.raises(SpawnError, match="overlaps robot 'a'"):
        world.add_robot("c", LIGHT, Pose2D(0.3, 0.0, 0))
    world.add_robot("d", LIGHT, Pose2D(1.0, 0.0, 0))
    assert set(world.robots) == {"a", "d"}


def test_husky_moves_forward(world):
    world.add_robot("h", ModelSpec(type="husky"), Pose2D(0, 0, 0))
    world.command("h", 0.5, 0.0)
    run(world, 1.5)
    state = world.state("h")
    assert 0.4 < state.x < 0.8 and abs(state.y) < 0.05
    world.remove_robot("h")
    assert world.robots == {}
