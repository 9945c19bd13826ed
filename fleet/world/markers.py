"""RViz/Foxglove view of the world: visualization_msgs markers of obstacles and robots (pure).

In frame `world` (the world's fixed frame, that of ground_truth).  Each robot has namespace
`robot/<name>` with three markers: its footprint (id 0, red while in contact), a heading arrow
(id 1) and its name (id 2); obstacles have namespace `obstacles`, one marker each.  The world
publishes the whole scene on /world/markers and each robot's own markers on <ns>/markers.
"""

from __future__ import annotations

import math

from builtin_interfaces.msg import Duration, Time
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker

from fleet.world.description import ModelSpec, ObstacleSpec

FRAME = "world"
ROBOT_HEIGHT = 0.3  # drawn height of a robot's footprint (m)
OBSTACLE_COLOR = ColorRGBA(r=0.55, g=0.55, b=0.6, a=1.0)
ROBOT_COLOR = ColorRGBA(r=0.15, g=0.45, b=0.9, a=0.9)
CONTACT_COLOR = ColorRGBA(r=0.9, g=0.15, b=0.1, a=0.9)
TEXT_COLOR = ColorRGBA(r=1.0, g=1.0, b=1.0, a=1.0)
# Markers last a few publishing periods: a removed robot or obstacle disappears by itself.
LIFETIME = Duration(sec=2)


def _marker(namespace: str, marker_id: int, kind: int, stamp: Time) -> Marker:
    marker = Marker()
    marker.header.frame_id = FRAME
    marker.header.stamp = stamp
    marker.ns = namespace
    marker.id = marker_id
    marker.type = kind
    marker.action = Marker.ADD
    marker.lifetime = LIFETIME
    return marker


def _place(marker: Marker, x: float, y: float, z: float, yaw: float) -> None:
    marker.pose.position.x, marker.pose.position.y, marker.pose.position.z = x, y, z
    marker.pose.orientation.z, marker.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)


def obstacle_markers(obstacles: list[ObstacleSpec], stamp: Time) -> list[Marker]:
    markers = []
    for index, obstacle in enumerate(obstacles):
        if obstacle.type == "cylinder":
            marker = _marker("obstacles", index, Marker.CYLINDER, stamp)
            height = obstacle.height
            marker.scale.x = marker.scale.y = 2 * obstacle.radius
        else:
            marker = _marker("obstacles", index, Marker.CUBE, stamp)
            marker.scale.x, marker.scale.y = obstacle.size[0], obstacle.size[1]
            height = obstacle.size[2]
        marker.scale.z = height
        marker.color = OBSTACLE_COLOR
        marker.text = obstacle.name
        _place(marker, obstacle.x, obstacle.y, height / 2, obstacle.yaw)
        markers.append(marker)
    return markers


def robot_markers(
    name: str, model: ModelSpec, pose: tuple[float, float, float], in_contact: bool, stamp: Time
) -> list[Marker]:
    x, y, yaw = pose
    namespace = f"robot/{name}"
    if model.is_round:
        body = _marker(namespace, 0, Marker.CYLINDER, stamp)
        body.scale.x = body.scale.y = 2 * model.radius
        reach = model.radius
    else:
        body = _marker(namespace, 0, Marker.CUBE, stamp)
        body.scale.x, body.scale.y = model.length, model.width
        reach = model.length / 2
    body.scale.z = ROBOT_HEIGHT
    body.color = CONTACT_COLOR if in_contact else ROBOT_COLOR
    _place(body, x, y, ROBOT_HEIGHT / 2, yaw)

    heading = _marker(namespace, 1, Marker.ARROW, stamp)
    heading.scale.x, heading.scale.y, heading.scale.z = reach + 0.2, 0.06, 0.06
    heading.color = TEXT_COLOR
    _place(heading, x, y, ROBOT_HEIGHT + 0.02, yaw)

    label = _marker(namespace, 2, Marker.TEXT_VIEW_FACING, stamp)
    label.scale.z = 0.25
    label.color = TEXT_COLOR
    label.text = name
    _place(label, x, y, ROBOT_HEIGHT + 0.35, 0.0)
    return [body, heading, label]
