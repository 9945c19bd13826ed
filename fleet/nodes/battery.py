"""battery: a simulated battery drained by time and by motion.

Subscribes `odom` (nav_msgs/Odometry; |linear speed| drives the motion draw), publishes
`battery` (sensor_msgs/BatteryState) at publish_rate and `diagnostics`.  Energy is integrated on
the node clock, so under use_sim_time the battery drains with simulated, not wall, time.
power_supply_health is GOOD, or DEAD once the charge is below critical_threshold; below
low_threshold the diagnostics level is WARN.
"""

from __future__ import annotations

import math
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import BatteryState

from fleet.nodes import models, parameters
from fleet.nodes.common import ERROR, OK, WARN, FleetNode, main_for, seconds


class BatteryNode(FleetNode):
    PARAMETERS = parameters.BATTERY
    RULES = parameters.BATTERY_RULES

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__("battery", **node_kwargs)
        p = self.params
        self.model = models.BatteryModel(
            capacity_wh=p["capacity"],
            energy_wh=p["capacity"] * p["initial_percentage"],
            idle_draw_w=p["idle_draw"],
            motion_draw_w_per_mps=p["motion_draw"],
        )
        self._last_time: float | None = None  # node-clock seconds of the last integration
        self.create_subscription(Odometry, "odom", self._on_odom, qos_profile_sensor_data)
        self.battery_pub = self.create_publisher(BatteryState, "battery", 10)
        self._timer = self.create_timer(1.0 / p["publish_rate"], self._publish)

    def on_parameters_changed(self, names: set[str]) -> None:
        self._integrate()  # the energy used so far was drawn under the old parameters
        p = self.params
        if "capacity" in names:
            # Keep the charge fraction: a new capacity describes a different battery, not a refill.
            fraction = self.model.fraction
            self.model.capacity_wh = p["capacity"]
            self.model.energy_wh = fraction * p["capacity"]
        if "initial_percentage" in names:
            # Setting it live is how an operator recharges (or drains) the simulated battery.
            self.model.energy_wh = p["initial_percentage"] * self.model.capacity_wh
        self.model.idle_draw_w = p["idle_draw"]
        self.model.motion_draw_w_per_mps = p["motion_draw"]
        if "publish_rate" in names:
            self.destroy_timer(self._timer)
            self._timer = self.create_timer(1.0 / p["publish_rate"], self._publish)

    def _integrate(self) -> None:
        """Drain the energy used since the last call at the current draw."""
        if self.sim_time_waiting():
            return  # ROS time is zero until /clock arrives: nothing to measure from yet
        now = seconds(self)
        if self._last_time is not None:
            # A clock that went backwards (a restarted simulation) drains nothing.
            self.model.advance(now - self._last_time)
        self._last_time = now

    def _on_odom(self, msg: Odometry) -> None:
        self._integrate()
        v = msg.twist.twist.linear
        self.model.speed = math.sqrt(v.x * v.x + v.y * v.y + v.z * v.z)

    def health(self) -> str:
        p = self.params
        return models.battery_health(self.model.fraction, p["low_threshold"], p["critical_threshold"])

    def _publish(self) -> None:
        self._integrate()
        msg = BatteryState()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = ""
        nan = float("nan")
        # Only energy is simulated: electrical quantities are unknown, which NaN says.
        msg.voltage = msg.temperature = msg.current = msg.charge = nan
        msg.capacity = msg.design_capacity = nan
        msg.percentage = float(self.model.fraction)
        msg.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        msg.power_supply_health = (
            BatteryState.POWER_SUPPLY_HEALTH_DEAD if self.health() == "dead" else BatteryState.POWER_SUPPLY_HEALTH_GOOD
        )
        msg.power_supply_technology = BatteryState.POWER_SUPPLY_TECHNOLOGY_UNKNOWN
        msg.present = True
        msg.location = self.get_fully_qualified_name()
        self.battery_pub.publish(msg)

    def diagnose(self) -> tuple[int, str, dict[str, Any]]:
        health = self.health()
        level, word = {"good": (OK, "ok"), "low": (WARN, "low"), "dead": (ERROR, "dead")}[health]
        message = f"{word}: {self.model.fraction * 100:.0f}% left"
        if self.sim_time_waiting():
            level, message = WARN, "waiting for /clock (use_sim_time)"
        draw = self.model.draw_w
        return (
            level,
            message,
            {
                "percentage": self.model.fraction,
                "energy_wh": self.model.energy_wh,
                "capacity_wh": self.model.capacity_wh,
                "draw_w": draw,
                "speed": self.model.speed,
                "remaining_s": self.model.energy_wh * 3600.0 / draw if draw > 0 else math.inf,
                "health": health,
            },
        )


def main(argv: list[str] | None = None) -> int:
    return main_for(BatteryNode, "battery", argv)


if __name__ == "__main__":
    raise SystemExit(main())
