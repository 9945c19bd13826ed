"""world.yaml validation: defaults, the documented schema, and one located error per problem."""

import math

import pytest

from fleet.world.description import WorldError, parse_world

DOCUMENTED = """
fleet: two_robots
physics_rate: 240.0
real_time: true
clock_rate: 100.0
obstacles:
- {name: wall_north, type: box, position: [0.0, 5.0], yaw: 0.0, size: [10.0, 0.2, 1.0]}
- {name: pillar, type: cylinder, position: [2.0, 2.0], radius: 0.3, height: 1.0}
robots:
- name: robot1
  namespace: /robot1
  model: {type: light, radius: 0.2, max_linear_speed: 1.0, max_angular_speed: 2.5}
  pose: {x: 0.0, y: 0.0, yaw: 0.0}
  lidar: {beams: 360, rate: 10.0, range_min: 0.12, range_max: 8.0}
  odom_rate: 50.0
  cmd_timeout: 0.5
  ground_truth: false
- name: robot2
  model: {type: husky}
  pose: {x: 3, y: 0}
"""


def test_documented_example_parses_with_defaults():
    world = parse_world(DOCUMENTED)
    assert world.fleet == "two_robots" and world.physics_rate == 240.0
    wall, pillar = world.obstacles
    assert wall.type == "box" and wall.size == (10.0, 0.2, 1.0) and wall.height == 1.0
    assert pillar.type == "cylinder" and pillar.radius == 0.3
    robot1, robot2 = world.robots
    assert robot1.namespace == "/robot1" and robot1.lidar.beams == 360
    assert math.isclose(robot1.lidar.increment, 2 * math.pi / 360)
    assert robot2.namespace == "/robot2" and robot2.model.type == "husky"
    assert (robot2.model.length, robot2.model.width) == (0.99, 0.68)
    assert robot2.pose.x == 3.0 and robot2.odom_rate == 50.0 and robot2.cmd_timeout == 0.5


def test_wall_is_a_box_and_empty_world_is_fine():
    world = parse_world("obstacles:\n- {name: w, type: wall, position: [1, 2], size: [3, 0.1, 1]}\n")
    assert world.obstacles[0].type == "box" and world.robots == ()


@pytest.mark.parametrize(
    "text, where, words",
    [
        ("robots:\n- name: r1\n  pose: {x: 1, y: oops}\n", ":3:", "'y' must be a number"),
        ("robots:\n- name: r1\n- name: r1\n", ":3:", "duplicate robot name 'r1'"),
        ("robots:\n- name: 9lives\n", ":2:", "not a valid name"),
        ("robots:\n- name: r1\n  model: {type: tank}\n", ":3:", "unknown model type 'tank'"),
        ("robots:\n- name: r1\n  lidar: {range_min: 5, range_max: 1}\n", ":3:", "range_min must be below range_max"),
        ("robots:\n- name: r1\n  odom_rate: 0\n", ":3:", "'odom_rate' must be > 0"),
        ("robots:\n- name: r1\n  colour: red\n", ":3:", "unknown key 'colour'"),
        ("obstacles:\n- {name: c, type: cylinder, position: [0, 0]}\n", ":2:", "missing 'radius'"),
        (
            "obstacles:\n- {name: b, type: box, position: [0], size: [1, 1, 1]}\n",
            ":2:",
            "'position' must be a list of 2",
        ),
        ("robots: [\n", ":", "invalid YAML"),
        ("physics_rate: -1\n", ":1:", "'physics_rate' must be at least 50 steps a second"),
    ],
)
def test_errors_name_file_line_and_problem(text, where, words):
    with pytest.raises(WorldError) as caught:
        parse_world(text, "w.yaml")
    message = str(caught.value)
    assert message.startswith("w.yaml") and where in message and words in message, message
    assert "\n" not in message


@pytest.mark.parametrize(
    "text, message",
    [
        ("robots:\n- name: r1\n  name: r2\n", "w.yaml:3:3: duplicate key 'name'"),
        ("robots:\n- {name: r1, 1: 2}\n", "w.yaml:2:17: unknown key '1' in robot (allowed: cmd_timeout, ground_truth,"),
        ("robots:\n- name: r1\n  model: {colour: red}\n", "w.yaml:3:19: unknown key 'colour' in robot 'r1'.model"),
        (
            "robots:\n- name: r1\n  lidar: {beams: 0}\n",
            "w.yaml:3:18: robot 'r1'.lidar: 'beams' must be in 1..4096, got 0",
        ),
        (
            "robots:\n- name: r1\n  ground_truth:\n",
            "w.yaml:3:16: robot 'r1': 'ground_truth' must be true or false, got None",
        ),
        (
            "obstacles:\n- {name: b, type: box, position: [0, 0], size: [1, 0]}\n",
            "w.yaml:2:48: obstacle 'b': size values",
        ),
        ("obstacles: [{name: b, type: tank, position: [0, 0]}]\n", "w.yaml:1:29: obstacle 'b': unknown type 'tank'"),
    ],
)
def test_more_errors_keep_their_words_and_places(text, message):
    with pytest.raises(WorldError) as caught:
        parse_world(text, "w.yaml")
    assert str(caught.value).startswith(message), str(caught.value)


def test_a_number_without_value_is_its_default_and_a_full_size_holds_the_height():
    world = parse_world(
        "robots:\n- {name: r1, odom_rate: , model: {type: racecar}}\n"
        "obstacles:\n- {name: b, type: box, position: [0, 0], size: [1, 1, 2], height: -1}\n"
    )
    assert world.robots[0].odom_rate == 50.0 and (world.robots[0].model.length, world.robots[0].model.width) == (
        0.55,
        0.3,
    )
    assert world.obstacles[0].size == (1.0, 1.0, 2.0) and world.obstacles[0].height == 2.0


@pytest.mark.parametrize(
    "text, message",
    [
        # A size, radius or height no world holds: the lidar would cut it into endless 1 m pieces.
        (
            "obstacles:\n- {name: crate, type: box, position: [2.5, 1.5], size: [1.0e+300, 0.5, 0.5]}\n",
            "w.yaml:2:57: obstacle 'crate': 'size' must be at most 10000 m (the world is 10000 m across), got 1e+300",
        ),
        (
            "obstacles:\n- {name: crate, type: box, position: [0, 0], size: [1, 1], height: 1.0e+6}\n",
            "w.yaml:2:68: obstacle 'crate': 'height' must be at most 10000 m (the world is 10000 m across), got 1e+06",
        ),
        (
            "obstacles:\n- {name: silo, type: cylinder, position: [0, 0], radius: 5001}\n",
            "w.yaml:2:58: obstacle 'silo': 'radius' must be at most 5000 m (the world is 10000 m across), got 5001",
        ),
        # Places beyond the world's extent.
        (
            "obstacles:\n- {name: crate, type: box, position: [0, -1.0e+6], size: [1, 1, 1]}\n",
            "w.yaml:2:42: obstacle 'crate': 'position' must be in -5000..5000 m (the world's extent), got -1e+06",
        ),
        (
            "robots:\n- {name: r1, pose: {x: 400, y: -9000}}\n",
            "w.yaml:2:32: robot 'r1'.pose: 'y' must be in -5000..5000 m (the world's extent), got -9000",
        ),
        # Rates the world cannot keep.
        (
            "physics_rate: 0.001\n",
            "w.yaml:1:15: world: 'physics_rate' must be at least 50 steps a second (one per message of the "
            "default 50 Hz odometry; slower steps drive URDF models off course), got 0.001",
        ),
        (
            "physics_rate: 240\nclock_rate: 1000\n",
            "w.yaml:2:13: clock_rate 1000 Hz is faster than the world publishes it (once per physics step at "
            "physics_rate 240): at most 240 Hz",
        ),
        (
            "physics_rate: 100\nrobots:\n- {name: r1, odom_rate: 200}\n",
            "w.yaml:3:25: robot 'r1': odom_rate 200 Hz is faster than the world publishes it (once per physics "
            "step at physics_rate 100): at most 100 Hz",
        ),
        (
            "robots:\n- {name: r1, lidar: {rate: 100}}\n",
            "w.yaml:2:28: robot 'r1': lidar rate 100 Hz is faster than the world publishes it (once every 4 "
            "physics steps at physics_rate 240): at most 60 Hz",
        ),
    ],
)
def test_what_the_world_cannot_hold_or_keep_up_with_is_refused_in_one_line(text, message):
    with pytest.raises(WorldError) as caught:
        parse_world(text, "w.yaml")
    assert str(caught.value) == message


def test_the_limits_themselves_and_a_slow_physics_are_accepted():
    world = parse_world(
        "physics_rate: 50\n"
        "obstacles:\n"
        "- {name: wall, type: wall, position: [-5000, 5000], size: [10000, 0.2, 10000]}\n"
        "- {name: silo, type: cylinder, position: [4000, 0], radius: 5000, height: 10000}\n"
        "robots:\n"
        "- {name: r1, pose: {x: 400, y: -900}, odom_rate: 50, lidar: {rate: 50}}\n"
    )
    assert world.obstacles[0].size == (10000.0, 0.2, 10000.0) and world.robots[0].pose.y == -900.0
    assert world.clock_rate == 50.0  # /clock's default, 100 Hz, at most once per physics step
    assert parse_world("physics_rate: 240\n").clock_rate == 100.0


@pytest.mark.parametrize(
    "text, message",
    [
        (
            "physics_rate: 1.0e3\n",
            "w.yaml:1:15: world: 'physics_rate' must be a number, got '1.0e3' (YAML reads 1.0e3 as text: write 1.0e+3)",
        ),
        (
            "obstacles:\n- {name: crate, type: box, position: [1e2, 0], size: [1, 1, 1]}\n",
            "w.yaml:2:39: obstacle 'crate': 'position' must contain numbers, got '1e2' (YAML reads 1e2 as text: "
            "write 1.0e+2)",
        ),
        # Quoted as YAML writes a float: text on purpose, nothing to suggest.
        ("clock_rate: '1.0e+3'\n", "w.yaml:1:13: world: 'clock_rate' must be a number, got '1.0e+3'"),
    ],
)
def test_a_number_yaml_reads_as_text_says_how_to_write_it(text, message):
    with pytest.raises(WorldError) as caught:
        parse_world(text, "w.yaml")
    assert str(caught.value) == message
