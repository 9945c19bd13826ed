"""RViz-ready world: a real world process publishes visualization_msgs/MarkerArray of its
obstacles and robots on /world/markers, and each robot's own on <ns>/markers; a robot's marker
follows it and turns red when it touches something."""

from __future__ import annotations

from typing import Any

import pytest

pytestmark = pytest.mark.integration

WORLD = """\
fleet: markers
obstacles:
- {name: wall, type: box, position: [1.2, 0.0], size: [0.2, 4.0, 1.0]}
- {name: post, type: cylinder, position: [-3.0, 3.0], radius: 0.3, height: 2.0}
robots:
- {name: robot1, pose: {x: 0.0, y: 0.0}, cmd_timeout: 5.0}
- {name: robot2, namespace: /team/robot2, pose: {x: -2.0, y: -2.0, yaw: 1.0}}
"""


@pytest.fixture
def world(start_world):
    return start_world(WORLD)[2]


def by_id(array) -> dict[tuple[str, int], Any]:
    return {(marker.ns, marker.id): marker for marker in array.markers}


def test_world_publishes_markers_of_obstacles_and_robots(world):
    from geometry_msgs.msg import Twist
    from visualization_msgs.msg import Marker, MarkerArray

    from fleet.testing.ros import RosProbe

    with RosProbe("rviz_stand_in") as probe:
        scene = probe.subscribe("/world/markers", MarkerArray)
        own = probe.subscribe("/team/robot2/markers", MarkerArray)
        probe.wait_until(lambda: scene.last and own.last, 30, "markers on /world/markers and /team/robot2/markers")

        markers = by_id(scene.last)
        assert set(markers) == {("obstacles", 0), ("obstacles", 1)} | {
            (f"robot/{name}", i) for name in ("robot1", "robot2") for i in (0, 1, 2)
        }
        wall, post = markers[("obstacles", 0)], markers[("obstacles", 1)]
        assert (wall.type, wall.scale.x, wall.scale.y, wall.scale.z) == (Marker.CUBE, 0.2, 4.0, 1.0)
        assert (post.type, post.scale.x, post.scale.z) == (Marker.CYLINDER, 0.6, 2.0)
        assert post.pose.position.x == -3.0 and post.pose.position.z == 1.0
        assert all(marker.header.frame_id == "world" for marker in scene.last.markers)
        label = markers[("robot/robot2", 2)]
        assert label.type == Marker.TEXT_VIEW_FACING and label.text == "robot2"
        assert {(m.ns, m.id) for m in own.last.markers} == {("robot/robot2", i) for i in (0, 1, 2)}
        heading = by_id(own.last)[("robot/robot2", 1)]
        assert heading.type == Marker.ARROW and abs(heading.pose.orientation.z - 0.4794) < 1e-3  # sin(1.0 / 2)

        # robot1 drives into the wall: its marker follows and turns red on contact.
        start = markers[("robot/robot1", 0)]
        assert start.color.r < 0.5

        def touching():
            forward = Twist()
            forward.linear.x = 0.5
            probe.publish("/robot1/cmd_vel", forward)
            body = by_id(scene.last)[("robot/robot1", 0)]
            return body if body.color.r > 0.5 else None

        body = probe.wait_until(touching, 30, "robot1's marker red against the wall")
        assert 0.7 < body.pose.position.x < 1.0  # at the wall (its face at 1.1, radius 0.2)
