"""numpy lidar: distances to walls, robots and cylinders; REP-117 out-of-range values."""

import math

import numpy as np

from fleet.world.geometry import Shape, overlaps
from fleet.world.lidar import Scene, beam_angles, cast

ANGLES = beam_angles(-math.pi, 2 * math.pi / 360, 360)  # beam 180 looks straight ahead


def scan(shapes, owners, x=0.0, y=0.0, yaw=0.0, owner=0, range_max=8.0):
    return cast(Scene.build(shapes, owners), x, y, yaw, ANGLES, 0.12, range_max, owner=owner)


def test_wall_ahead_at_known_distance():
    wall = Shape("rect", 3.0, 0.0, 0.0, half_x=0.1, half_y=5.0)  # face at x = 2.9
    ranges = scan([wall], [-1])
    assert abs(ranges[180] - 2.9) < 0.02
    assert abs(ranges[180 + 30] - 2.9 / math.cos(math.radians(30))) < 0.03
    assert np.isinf(ranges[0]) and ranges[0] > 0  # behind: nothing within range_max


def test_rotated_robot_sees_wall_on_its_side():
    wall = Shape("rect", 0.0, 2.0, 0.3, half_x=5.0, half_y=0.1)  # tilted wall north of the robot
    ranges = scan([wall], [-1], yaw=math.pi / 2)
    expected = 2.0 - 0.1 / math.cos(0.3)  # vertical distance to the lower face along x = 0
    assert abs(ranges[180] - expected) < 0.03


def test_other_robot_shows_up_and_own_body_does_not():
    me = Shape("circle", 0.0, 0.0, radius=0.2)
    other = Shape("circle", 2.0, 0.0, radius=0.2)
    ranges = scan([me, other], [0, 1])
    assert abs(ranges[180] - 1.8) < 0.02
    assert np.isinf(ranges[0])  # its own body is not a return
    # the other robot subtends about +-6 degrees at 1.8 m
    assert np.isfinite(ranges[180 + 5]) and np.isinf(ranges[180 + 8])


def test_cylinder_beyond_range_max_is_inf():
    far = Shape("circle", 10.0, 0.0, radius=0.3)
    ranges = scan([far], [-1], range_max=8.0)
    assert np.all(np.isposinf(ranges))
    ranges = scan([far], [-1], range_max=12.0)
    assert abs(ranges[180] - 9.7) < 0.02


def test_closer_than_range_min_is_minus_inf():
    touching = Shape("circle", 0.15, 0.0, radius=0.1)  # surface at 0.05 m
    ranges = scan([touching], [-1])
    assert np.isneginf(ranges[180])


def test_overlap_tests():
    c = Shape("circle", 0, 0, radius=0.2)
    assert overlaps(c, Shape("circle", 0.35, 0, radius=0.2))
    assert not overlaps(c, Shape("circle", 0.45, 0, radius=0.2))
    box = Shape("rect", 1.0, 0, 0.0, half_x=0.5, half_y=0.5)
    assert overlaps(Shape("circle", 0.35, 0, radius=0.2), box)
    assert not overlaps(Shape("circle", 0.25, 0, radius=0.2), box)
    assert not overlaps(Shape("circle", 0.4, 0.7, radius=0.2), box)  # near the corner but outside
    assert overlaps(
        Shape("rect", 0, 0, math.pi / 4, half_x=0.5, half_y=0.1), Shape("rect", 0.4, 0.4, 0.0, half_x=0.1, half_y=0.1)
    )
    assert not overlaps(
        Shape("rect", 0, 0, math.pi / 4, half_x=0.5, half_y=0.1), Shape("rect", 0.4, -0.4, 0.0, half_x=0.1, half_y=0.1)
    )


def test_matches_pybullet_ray_tests_in_a_random_scene():
    """The numpy lidar agrees with pybullet's own ray casts (full circle and a partial fan)."""
    import pybullet as pb

    rng = np.random.default_rng(7)
    client = pb.connect(pb.DIRECT)
    try:
        shapes: list[Shape] = []
        sensor = Shape("circle", 0.0, 0.0, radius=0.3)
        while len(shapes) < 12:
            x, y = rng.uniform(-6, 6, 2)
            if rng.random() < 0.5:
                shape = Shape("circle", x, y, radius=rng.uniform(0.1, 0.6))
            else:
                shape = Shape(
                    "rect", x, y, rng.uniform(-3, 3), half_x=rng.uniform(0.05, 3.0), half_y=rng.uniform(0.05, 1.0)
                )
            if overlaps(shape, sensor):
                continue  # keep the sensor outside every shape
            if shape.kind == "circle":
                col = pb.createCollisionShape(pb.GEOM_CYLINDER, radius=shape.radius, height=2.0, physicsClientId=client)
            else:
                col = pb.createCollisionShape(
                    pb.GEOM_BOX, halfExtents=(shape.half_x, shape.half_y, 1.0), physicsClientId=client
                )
            pb.createMultiBody(
                0,
                col,
                basePosition=(x, y, 0.0),
                baseOrientation=pb.getQuaternionFromEuler((0, 0, shape.yaw)),
                physicsClientId=client,
            )
            shapes.append(shape)
        scene = Scene.build(shapes, [-1] * len(shapes))
        for yaw, angles in ((0.4, ANGLES), (-2.0, beam_angles(-1.2, 2.4 / 99, 100))):
            ours = cast(scene, 0.0, 0.0, yaw, angles, 0.05, 8.0)
            ends = [(8.0 * math.cos(a + yaw), 8.0 * math.sin(a + yaw), 0.0) for a in angles]
            theirs = np.array(
                [
                    hit[2] * 8.0 if hit[0] >= 0 else np.inf
                    for hit in pb.rayTestBatch([(0.0, 0.0, 0.0)] * len(angles), ends, physicsClientId=client)
                ]
            )
            both = np.isfinite(theirs)
            assert np.array_equal(np.isfinite(ours), both) or np.sum(np.isfinite(ours) != both) <= 2  # grazing beams
            assert np.all(np.abs(ours[both & np.isfinite(ours)] - theirs[both & np.isfinite(ours)]) < 0.01)
            assert both.sum() > 10
    finally:
        pb.disconnect(client)
