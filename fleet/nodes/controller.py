"""controller: drives a robot along a list of waypoints.

Subscribes `odom` (nav_msgs/Odometry) and `battery` (sensor_msgs/BatteryState), publishes
`cmd_vel` (geometry_msgs/Twist) at control_rate on the node clock (so use_sim_time paces it),
`~/goal` (geometry_msgs/PointStamped, transient local: the waypoint being driven to, sent when it
changes) and `diagnostics`.  Publishes a zero twist while it has no odometry, after the last
waypoint of a non-looping route, and while the battery reports DEAD health.
"""

from __future__ import annotations

import math
from typing import Any

from geometry_msgs.msg import PointStamped, Twist
from nav_msgs.msg import Odometry
from rclpy.qos import QoSDurabilityPolicy, QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import BatteryState

from fleet.nodes import models, parameters
from fleet.nodes.common import ERROR, OK, WARN, FleetNode, main_for


class ControllerNode(FleetNode):
    PARAMETERS = parameters.CONTROLLER
    RULES = parameters.CONTROLLER_RULES

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__("controller", **node_kwargs)
        self.follower = models.WaypointFollower(models.pairs(self.params["waypoints"]), loop=self.params["loop"])
        self.pose: tuple[float, float, float] | None = None
        self.frame_id = "odom"
        self.battery_dead = False
        self.distance = math.nan
        self.command = (0.0, 0.0)
        self._published_goal: tuple | None = None

        # Sensor QoS (best effort) matches both reliable and best-effort publishers.
        self.create_subscription(Odometry, "odom", self._on_odom, qos_profile_sensor_data)
        self.create_subscription(BatteryState, "battery", self._on_battery, qos_profile_sensor_data)
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel", 10)
        latched = QoSProfile(depth=1, durability=QoSDurabilityPolicy.TRANSIENT_LOCAL)
        self.goal_pub = self.create_publisher(PointStamped, "~/goal", latched)
        self._timer = self.create_timer(1.0 / self.params["control_rate"], self._tick)

    def on_parameters_changed(self, names: set[str]) -> None:
        if "waypoints" in names:
            self.follower.set_waypoints(models.pairs(self.params["waypoints"]))
        if "loop" in names:
            self.follower.set_loop(self.params["loop"])
        if "control_rate" in names:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / self.params["control_rate"], self._tick)

    def _on_odom(self, msg: Odometry) -> None:
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
        self.pose = (p.x, p.y, models.yaw_from_quaternion(q.x, q.y, q.z, q.w))
        self.frame_id = msg.header.frame_id or self.frame_id

    def _on_battery(self, msg: BatteryState) -> None:
        self.battery_dead = msg.power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_DEAD

    def _tick(self) -> None:
        speed, turn = 0.0, 0.0
        if self.pose is not None:
            x, y, yaw = self.pose
            # Waypoints advance even while stopped, so the reported progress stays true.
            self.distance = self.follower.update(x, y, self.params["goal_tolerance"])
            if not self.follower.finished and not self.battery_dead:
                speed, turn = models.steer(
                    x,
                    y,
                    yaw,
                    self.follower.goal,
                    self.params["max_speed"],
                    self.params["max_turn_rate"],
                )
            self._publish_goal()
        self.command = (speed, turn)
        twist = Twist()
        twist.linear.x, twist.angular.z = speed, turn
        self.cmd_pub.publish(twist)

    def _publish_goal(self) -> None:
        key = (self.follower.index, self.follower.goal, self.frame_id)
        if key == self._published_goal:
            return
        self._published_goal = key
        goal_x, goal_y = self.follower.goal
        self.get_logger().info(f"heading to waypoint {self.follower.index} ({goal_x:.2f}, {goal_y:.2f})")
        msg = PointStamped()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.frame_id
        msg.point.x, msg.point.y = self.follower.goal
        self.goal_pub.publish(msg)

    def state(self) -> str:
        if self.pose is None:
            return "waiting for odom"
        if self.battery_dead:
            return "stopped: battery dead"
        if self.follower.finished:
            return "finished"
        return "driving"

    def diagnose(self) -> tuple[int, str, dict[str, Any]]:
        state = self.state()
        level = {"driving": OK, "finished": OK, "waiting for odom": WARN}.get(state, ERROR)
        if self.sim_time_waiting():
            level, state = WARN, "waiting for /clock (use_sim_time)"
        goal = self.follower.goal
        return (
            level,
            state,
            {
                "waypoint_index": self.follower.index,
                "waypoint_count": len(self.follower.waypoints),
                "goal_x": goal[0],
                "goal_y": goal[1],
                "distance_to_goal": self.distance,
                "laps": self.follower.laps,
                "linear_x": self.command[0],
                "angular_z": self.command[1],
                "max_speed": self.params["max_speed"],
                "battery_dead": self.battery_dead,
            },
        )


def main(argv: list[str] | None = None) -> int:
    return main_for(ControllerNode, "controller", argv)


if __name__ == "__main__":
    raise SystemExit(main())
