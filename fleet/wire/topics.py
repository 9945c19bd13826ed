"""Which ROS topics cross computers, and which way (pure).

The world owns, per robot, what the world publishes (odom, scan, ground_truth) and what it takes
(cmd_vel, battery), plus the fleet-wide /clock.  With the `zenoh` transport a robot on another
agent than the world's gets the world's side of its topics through the two agents' bridges,
and the world gets the robot's side the same way.  Robots on the world's agent need no bridge.
QoS below is that of the publishers (fleet/world/ros_bridge.py, fleet_nodes), which the
receiving bridge republishes with, so subscribers match as they would locally.

Templates add topics of their own (`share(...)`, fleet/expand/shared.py): such a topic leaves
an agent whose robots publish it for every other agent whose robots subscribe to it, and only
those (Zenoh delivers a message only where a bridge declared a subscriber for its key).
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from fleet.wire.protocol import BridgeRoutes, TopicRoute


@dataclass(frozen=True)
class Crossing:
    suffix: str  # after the robot's namespace
    type: str
    from_world: bool  # published by the world (else by the robot's nodes)
    reliable: bool = True
    depth: int = 10


ROBOT_TOPICS = (
    Crossing("odom", "nav_msgs/msg/Odometry", from_world=True),
    Crossing("scan", "sensor_msgs/msg/LaserScan", from_world=True),
    Crossing("ground_truth", "geometry_msgs/msg/PoseStamped", from_world=True),
    Crossing("cmd_vel", "geometry_msgs/msg/Twist", from_world=False),
    Crossing("battery", "sensor_msgs/msg/BatteryState", from_world=False),
)
CLOCK = TopicRoute(name="/clock", type="rosgraph_msgs/msg/Clock")


@dataclass(frozen=True)
class SharedRoute:
    """A topic a robot's template shares, on that robot's agent."""

    agent: str
    route: TopicRoute
    publishes: bool  # the robot's nodes publish it
    subscribes: bool  # the robot's nodes subscribe to it


def world_topic_names(robot_namespaces: Iterable[str]) -> set[str]:
    """Every topic the world's side carries for these robots, and /clock."""
    names = {
        f"{namespace.rstrip('/')}/{crossing.suffix}" for namespace in robot_namespaces for crossing in ROBOT_TOPICS
    }
    return names | {CLOCK.name}


def bridge_routes(
    world_agent: str | None, robots: list[tuple[str, str, str]], shared: Iterable[SharedRoute] = ()
) -> dict[str, BridgeRoutes]:
    """agent -> the topics its bridge exports and imports.

    `robots`: (name, namespace, agent) of every robot the world hosts (a real one's topics are
    its own); `shared`: the topics the templates of the fleet's robots share (one type and QoS
    per topic name)."""
    routes: dict[str, BridgeRoutes] = {}
    if world_agent is not None:
        _world_routes(routes, world_agent, robots)
    _shared_routes(routes, shared)
    return routes


def _shared_routes(routes: dict[str, BridgeRoutes], shared: Iterable[SharedRoute]) -> None:
    publishing: dict[str, set[str]] = {}  # topic -> agents with robots publishing it
    subscribing: dict[str, set[str]] = {}
    route_of: dict[str, TopicRoute] = {}
    for declared in shared:
        route_of.setdefault(declared.route.name, declared.route)
        if declared.publishes:
            publishing.setdefault(declared.route.name, set()).add(declared.agent)
        if declared.subscribes:
            subscribing.setdefault(declared.route.name, set()).add(declared.agent)
    for name in sorted(route_of):
        publishers, subscribers = publishing.get(name, set()), subscribing.get(name, set())
        for agent in sorted(publishers | subscribers):
            if agent in publishers and subscribers - {agent}:
                routes.setdefault(agent, BridgeRoutes()).exports.append(route_of[name])
            if agent in subscribers and publishers - {agent}:
                routes.setdefault(agent, BridgeRoutes()).imports.append(route_of[name])


def _world_routes(routes: dict[str, BridgeRoutes], world_agent: str, robots: list[tuple[str, str, str]]) -> None:
    world = routes.setdefault(world_agent, BridgeRoutes())
    remote_agents = sorted({agent for _, _, agent in robots if agent != world_agent})
    if remote_agents:
        world.exports.append(CLOCK)
    for agent in remote_agents:
        routes.setdefault(agent, BridgeRoutes()).imports.append(CLOCK)
    for _, namespace, agent in sorted(robots):
        if agent == world_agent:
            continue
        robot = routes[agent]
        for crossing in ROBOT_TOPICS:
            route = TopicRoute(
                name=f"{namespace.rstrip('/')}/{crossing.suffix}",
                type=crossing.type,
                reliable=crossing.reliable,
                depth=crossing.depth,
            )
            (world.exports if crossing.from_world else world.imports).append(route)
            (robot.imports if crossing.from_world else robot.exports).append(route)
