"""fleets/two_robots.yaml end to end, written with fleet.testing as a user would: both robots
patrol on sim time in one world, each on its own topics, robot2 at its own speed, a battery that
runs flat stops its robot, and a robot added by redeploying joins without disturbing the others."""

from __future__ import annotations

import itertools
import math

import pytest

from fleet.testing import running_fleet
from tests.e2e.e2e_helpers import TWO_ROBOTS, PoseWatch, RouteProgress, node_pids, odom_speeds, spec_with, wait_driving

pytestmark = pytest.mark.integration

ROBOTS = ("robot1", "robot2")
TOPICS = ("cmd_vel", "cmd_vel_nav", "odom", "scan", "battery", "diagnostics")


@pytest.fixture(scope="module")
def two_robots(tmp_path_factory):
    with running_fleet(TWO_ROBOTS, directory=tmp_path_factory.mktemp("two_robots")) as fleet:
        yield fleet


@pytest.fixture
def fleet(two_robots):
    """The module's fleet as fleets/two_robots.yaml describes it (an earlier test may have changed
    it; a deploy of what already runs changes nothing)."""
    two_robots.deploy(TWO_ROBOTS, sets=[])
    two_robots.wait_desired_state()
    wait_driving(two_robots, ROBOTS)
    return two_robots


def test_both_robots_patrol_their_waypoints_on_sim_time(fleet):
    from nav_msgs.msg import Odometry

    assert [fleet.get_param(robot, "controller", "use_sim_time") for robot in ROBOTS] == [True, True]
    odom = fleet.subscribe("robot1", "odom", Odometry)
    routes = {robot: RouteProgress(fleet, robot) for robot in ROBOTS}
    contacts_before = fleet.contact_count()

    # Every waypoint of each route, in order (robot1's 8 m lap at 0.4 m/s takes ~25 s of sim time).
    fleet.wait_for(
        lambda: all([route.update() >= len(route.points) for route in routes.values()]),
        sim_timeout=45,
        what="robot1 and robot2 to reach each of their waypoints in order",
        explain=lambda: ", ".join(f"{r}: reached {p.reached}, next {p.next}" for r, p in routes.items()),
    )

    # Their clocks are the world's: odometry is stamped with sim time, not the wall clock.
    stamp = odom.last.header.stamp.sec + odom.last.header.stamp.nanosec * 1e-9
    assert abs(stamp - fleet.sim_time()) < 2.0, (stamp, fleet.sim_time())
    between = [c for c in fleet.contacts() if {c["a"], c["b"]} == set(ROBOTS)]
    assert not between and fleet.contact_count() >= contacts_before


def test_each_robot_has_its_own_topics(fleet):
    from nav_msgs.msg import Odometry

    expected = {fleet.topic(robot, topic) for robot in ROBOTS for topic in TOPICS}
    fleet.wait_for(
        lambda: expected <= set(fleet.ros.topics()),
        timeout=20,
        what="every robot topic in the ROS graph",
        explain=lambda: f"seen {sorted(fleet.ros.topics())}",
    )
    assert not {"/cmd_vel", "/odom", "/scan", "/battery"} & set(fleet.ros.topics())

    # Every node on a robot's topics belongs to that robot, or is the world (which serves them all).
    probe = fleet.ros.node

    def owners(name: str) -> set[tuple[str, str]] | None:
        """(namespace, node) of every endpoint on a topic but ours; None while discovery has not
        told yet which node an endpoint belongs to."""
        endpoints = probe.get_publishers_info_by_topic(name) + probe.get_subscriptions_info_by_topic(name)
        found = {(info.node_namespace, info.node_name) for info in endpoints if info.node_name != probe.get_name()}
        return None if any(node == "_NODE_NAME_UNKNOWN_" for _, node in found) else found

    for robot in ROBOTS:
        allowed = {(f"/{robot}", node) for node in ("controller", "battery", "safety")} | {("/", "world")}
        for topic in TOPICS:
            name = fleet.topic(robot, topic)
            found = fleet.wait_for(lambda name=name: owners(name), timeout=10, what=f"the nodes on {name}")
            assert found <= allowed, (name, found)

    # Each robot's odometry is its own: frames named after it, and positions matching its world pose.
    odom = {robot: fleet.subscribe(robot, "odom", Odometry) for robot in ROBOTS}
    fleet.wait_for(
        lambda: all(odom[robot].count >= 5 for robot in ROBOTS), sim_timeout=5, what="odometry of both robots"
    )
    for robot in ROBOTS:
        message = odom[robot].last
        assert (message.header.frame_id, message.child_frame_id) == (f"{robot}/odom", f"{robot}/base_link")
    # A command published to robot1 reaches robot1's cmd_vel (relayed by its safety node) only.
    from geometry_msgs.msg import Twist

    seen = {robot: fleet.subscribe(robot, "cmd_vel") for robot in ROBOTS}  # type from the graph
    ours = Twist()
    ours.linear.x = 0.123

    def relayed() -> bool:  # (and robot2's own commands seen for a while as we kept publishing)
        fleet.publish("robot1", "cmd_vel_nav", ours)
        return any(abs(m.linear.x - 0.123) < 1e-6 for m in seen["robot1"].messages) and seen["robot2"].count >= 10

    fleet.wait_for(
        relayed,
        sim_timeout=10,
        what="our command relayed to /robot1/cmd_vel",
        explain=lambda: f"{seen['robot1'].count} on robot1, {seen['robot2'].count} on robot2",
    )
    assert not any(abs(m.linear.x - 0.123) < 1e-6 for m in seen["robot2"].messages)
    # Each robot's parameters are its own, and checked: an out-of-range value is refused.
    accepted, reason = fleet.set_param("robot2", "safety", "safety_distance", 99.0)
    assert not accepted and "safety_distance" in reason, reason
    assert fleet.get_param("robot2", "safety", "safety_distance") == 0.4

    # robot2 starts at (4, 0) facing +y: its odom x axis is the world's y axis.
    fleet.spin(0.3)
    p1, p2 = odom["robot1"].last.pose.pose.position, odom["robot2"].last.pose.pose.position
    # (the world writes its status every 0.25 s: allow for what a robot drives meanwhile)
    assert fleet.pose("robot1").distance_to((p1.x, p1.y)) < 0.4
    assert fleet.pose("robot2").distance_to((4.0 - p2.y, p2.x)) < 0.4


def _stamp(message) -> float:
    return message.header.stamp.sec + message.header.stamp.nanosec * 1e-9


def _yaw(orientation) -> float:
    return 2 * math.atan2(orientation.z, orientation.w)


def _compose(parent: tuple[float, float, float], child: tuple[float, float, float]) -> tuple[float, float, float]:
    """A pose given in a frame whose own pose is `parent`, in the parent's frame (planar)."""
    px, py, pyaw = parent
    x, y, yaw = child
    c, s = math.cos(pyaw), math.sin(pyaw)
    return px + c * x - s * y, py + s * x + c * y, pyaw + yaw


def _distance_to_box(point: tuple[float, float], obstacle: dict) -> float:
    (cx, cy), yaw, (length, width, _) = obstacle["position"], obstacle["yaw"], obstacle["size"]
    c, s = math.cos(yaw), math.sin(yaw)
    dx, dy = point[0] - cx, point[1] - cy
    lx, ly = c * dx + s * dy, -s * dx + c * dy
    return math.hypot(max(abs(lx) - length / 2, 0.0), max(abs(ly) - width / 2, 0.0))


def test_odometry_and_scans_agree_with_ground_truth_through_the_robots_frames(fleet):
    """The frames a TF tree of the robot would hold (docs/architecture.md): `world` -> odom is the
    spawn pose, odom -> base_link the odometry's pose, base_link -> base_scan identity.  Chained,
    they put the odometry on the ground truth and each beam's return on an obstacle's surface."""
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import LaserScan

    robot = "robot2"  # spawned at (4, 0) facing +y: its odom frame is turned against the world's
    spawn = fleet.spec.robot(robot).pose
    world_to_odom = (spawn.x, spawn.y, spawn.yaw)
    odom = fleet.subscribe(robot, "odom", Odometry, keep=200)
    truth = fleet.subscribe(robot, "ground_truth", PoseStamped, keep=200)
    scans = fleet.subscribe(robot, "scan", LaserScan, keep=20)
    other = fleet.subscribe("robot1", "ground_truth", PoseStamped, keep=200)
    fleet.wait_for(lambda: scans.count >= 5 and other.count >= 50, sim_timeout=10, what="scans and ground truth")

    # Odometry and ground truth of one step carry the same stamp: chained with the spawn pose,
    # the odometry is the ground truth.
    by_stamp = {_stamp(m): m for m in truth.messages}
    pairs = [(m, by_stamp[_stamp(m)]) for m in odom.messages if _stamp(m) in by_stamp]
    assert len(pairs) >= 10, (len(pairs), odom.count, truth.count)
    for message, true in pairs:
        pose = message.pose.pose
        x, y, yaw = _compose(world_to_odom, (pose.position.x, pose.position.y, _yaw(pose.orientation)))
        assert math.hypot(x - true.pose.position.x, y - true.pose.position.y) < 1e-6
        assert abs(math.remainder(yaw - _yaw(true.pose.orientation), 2 * math.pi)) < 1e-6

    # Each finite return, from base_scan through the odometry at the scan's stamp (interpolated
    # between the two odometry messages around it, as tf2 does), lies on a wall, the crate or robot1.
    def pose_at(messages, when: float, pose_of) -> tuple[float, float, float] | None:
        ordered = sorted(messages, key=_stamp)
        for before, after in itertools.pairwise(ordered):
            t0, t1 = _stamp(before), _stamp(after)
            if t0 <= when <= t1:
                (x0, y0, a0), (x1, y1, a1) = pose_of(before), pose_of(after)
                k = (when - t0) / (t1 - t0) if t1 > t0 else 0.0
                return x0 + k * (x1 - x0), y0 + k * (y1 - y0), a0 + k * math.remainder(a1 - a0, 2 * math.pi)
        return None

    def odom_pose(m):
        return m.pose.pose.position.x, m.pose.pose.position.y, _yaw(m.pose.pose.orientation)

    def truth_pose(m):
        return m.pose.position.x, m.pose.position.y, _yaw(m.pose.orientation)

    boxes = fleet.world()["obstacles"]
    checked = 0
    for scan in list(scans.messages):
        assert scan.header.frame_id == f"{robot}/base_scan"
        in_odom = pose_at(odom.messages, _stamp(scan), odom_pose)
        robot1 = pose_at(other.messages, _stamp(scan), truth_pose)
        if in_odom is None or robot1 is None:
            continue
        base_scan = _compose(_compose(world_to_odom, in_odom), (0.0, 0.0, 0.0))
        for i, r in enumerate(scan.ranges):
            if not math.isfinite(r):
                continue
            x, y, _ = _compose(
                base_scan,
                (
                    r * math.cos(scan.angle_min + i * scan.angle_increment),
                    r * math.sin(scan.angle_min + i * scan.angle_increment),
                    0.0,
                ),
            )
            nearest = min(
                [_distance_to_box((x, y), box) for box in boxes]
                + [abs(math.hypot(x - robot1[0], y - robot1[1]) - 0.2)]  # robot1: a light robot of radius 0.2
            )
            assert nearest < 0.01, (scan.header.stamp, i, r, (x, y), nearest)
            checked += 1
    assert checked >= 100, checked


def test_robot2_drives_at_its_overridden_max_speed(fleet):
    from nav_msgs.msg import Odometry

    # The parameter each controller holds: the fleet default 0.4, robot2's override 0.8 ...
    assert fleet.get_param("robot1", "controller", "max_speed") == 0.4
    assert fleet.get_param("robot2", "controller", "max_speed") == 0.8
    # ... and the speed each robot really drives at, measured from its odometry over sim time.
    odom = {robot: fleet.subscribe(robot, "odom", Odometry, keep=3000) for robot in ROBOTS}

    def top_speed(robot: str) -> float:
        return max(odom_speeds(odom[robot].messages), default=0.0)

    fleet.wait_for(
        lambda: top_speed("robot1") > 0.36 and top_speed("robot2") > 0.72,
        sim_timeout=20,
        what="robot1 to reach ~0.4 m/s and robot2 ~0.8 m/s",
        explain=lambda: f"top speeds robot1 {top_speed('robot1'):.2f}, robot2 {top_speed('robot2'):.2f} m/s",
    )
    fleet.wait_sim(5.0)  # more legs of each route, for the upper bounds
    assert top_speed("robot1") < 0.45, top_speed("robot1")
    assert top_speed("robot2") < 0.88, top_speed("robot2")


def test_battery_drains_and_robot_stops_at_the_critical_level(fleet):
    from sensor_msgs.msg import BatteryState

    before = node_pids(fleet.status())
    # 0.02 Wh drains in a few seconds of sim time (5 W idle + 20 W per m/s).
    fleet.deploy(sets=["robot1.battery.capacity=0.02"])
    after = node_pids(fleet.status())
    assert after["robot2"] == before["robot2"] and after["world"] == before["world"]
    assert after["robot1"].isdisjoint(before["robot1"])
    assert fleet.get_param("robot1", "battery", "capacity") == 0.02

    battery = fleet.subscribe("robot1", "battery", BatteryState)
    fleet.wait_for(
        lambda: battery.last is not None and battery.last.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_DEAD,
        sim_timeout=30,
        what="robot1's battery to report DEAD",
        explain=lambda: f"levels {[round(m.percentage, 3) for m in battery.messages]}",
    )
    levels = [m.percentage for m in battery.messages]
    assert levels == sorted(levels, reverse=True) and levels[-1] <= 0.05 < levels[0], levels

    fleet.wait_for(lambda: abs(fleet.velocity("robot1")[0]) < 0.01, sim_timeout=3, what="robot1 to stop")
    stopped, robot2_at = fleet.pose("robot1"), fleet.pose("robot2")
    fleet.wait_sim(3.0)
    assert fleet.pose("robot1").distance_to(stopped) < 0.02  # it stays where its battery died
    assert fleet.pose("robot2").distance_to(robot2_at) > 0.3  # while robot2 patrols on


def test_robot_added_by_redeploy_joins_and_patrols(fleet, tmp_path):
    def add_robot3(data):
        data["robots"].append(
            {
                "name": "robot3",
                "pose": {"x": 5.0, "y": 0.5, "yaw": 0.0},
                "parameters": {"controller": {"waypoints": [0.5, 0.0, 0.5, 2.0, 0.0, 2.0, 0.0, 0.0]}},
            }
        )

    changed = spec_with(TWO_ROBOTS, tmp_path, add_robot3)
    before = node_pids(fleet.status())
    with PoseWatch(fleet, [*ROBOTS, "robot3"]) as watch:
        outcome = fleet.deploy(changed)
        fleet.wait_desired_state()
        # Joined at its spawn pose: the world's first report of it.  Its pose once the desired
        # state is reached may already be its first steps (its waypoints are in its odom frame,
        # which starts at the spawn pose: the first lies 0.5 m ahead).
        _, x, y = watch.samples["robot3"][0]
        assert math.hypot(x - 5.0, y - 0.5) < 0.3, watch.samples["robot3"][:3]
        # Its spawn pose is also its last waypoint ((0, 0) in its odom frame), so waiting for two
        # reached waypoints was met 0.2 m from it (and the others had driven under 0.5 m): it is
        # its waypoint 1 that shows it patrols, 2.5 m of driving ahead, past waypoint 0.
        route = RouteProgress(fleet, "robot3")

        def reached_waypoint_1() -> bool:
            route.update()
            return 1 in route.reached

        fleet.wait_for(reached_waypoint_1, sim_timeout=20, what="robot3 to reach its waypoint 1")

    changes = outcome.replies["local"].changes
    assert (changes.start, changes.hot_update, sorted(changes.unchanged)) == (["robot3"], ["world"], list(ROBOTS))
    after = node_pids(fleet.status())
    assert {name: after[name] for name in before} == before  # nobody else restarted
    for robot in ROBOTS:
        assert watch.largest_jump(robot) < 0.1, (robot, watch.largest_jump(robot))
        assert watch.path_length(robot) > 0.5, (robot, watch.path_length(robot))  # they kept driving


@pytest.mark.soak
def test_long_patrol_three_laps_without_touching(fleet):
    """Three full laps each (robot1's lap is ~25 s of sim time): no robot-robot contact, batteries
    drain slowly (50 Wh), nobody restarts."""
    before = node_pids(fleet.status())
    routes = {robot: RouteProgress(fleet, robot) for robot in ROBOTS}
    fleet.wait_for(
        lambda: all([route.update() >= 3 * len(route.points) for route in routes.values()]),
        sim_timeout=120,
        what="three laps of each robot",
        explain=lambda: ", ".join(f"{r}: reached {len(p.reached)}" for r, p in routes.items()),
    )
    assert not [c for c in fleet.contacts() if {c["a"], c["b"]} == set(ROBOTS)]
    assert all(0.5 < fleet.battery(robot) < 1.0 for robot in ROBOTS)
    assert node_pids(fleet.status()) == before
