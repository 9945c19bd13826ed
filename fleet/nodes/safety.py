"""safety: a velocity gate between a controller and the robot.

Subscribes `scan` (sensor_msgs/LaserScan) and `cmd_vel_in` (geometry_msgs/Twist), publishes
`cmd_vel_out` (Twist) and `diagnostics`.  Commands pass through unchanged, except:
- an obstacle closer than safety_distance within +-scan_half_angle of straight ahead zeroes
  forward speed (turning in place and reversing still pass, so the robot can get away);
- with no scan for scan_timeout (node clock) the output is a zero twist: driving blind is unsafe.
A new verdict acts at once: when a scan makes an earlier command unsafe, or the scan goes stale,
the gated command is re-published without waiting for the next input.
"""

from __future__ import annotations

import math
from typing import Any

from geometry_msgs.msg import Twist
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import LaserScan

from fleet.nodes import models, parameters
from fleet.nodes.common import ERROR, OK, WARN, FleetNode, main_for, seconds

WATCHDOG_PERIOD = 0.05  # s: how late a scan timeout may be noticed


class SafetyNode(FleetNode):
    PARAMETERS = parameters.SAFETY

    def __init__(self, **node_kwargs: Any) -> None:
        super().__init__("safety", **node_kwargs)
        self.last_scan: LaserScan | None = None
        self.last_scan_time: float | None = None  # node-clock seconds at reception
        self.nearest = math.inf
        self.last_input: Twist | None = None
        self.last_verdict = "no scan"
        self.gated_count = 0
        self.create_subscription(LaserScan, "scan", self._on_scan, qos_profile_sensor_data)
        self.create_subscription(Twist, "cmd_vel_in", self._on_cmd, 10)
        self.cmd_pub = self.create_publisher(Twist, "cmd_vel_out", 10)
        self.create_timer(WATCHDOG_PERIOD, self._react)

    def on_parameters_changed(self, names: set[str]) -> None:
        if "scan_half_angle" in names and self.last_scan is not None:
            self.nearest = self._nearest(self.last_scan)

    def _nearest(self, scan: LaserScan) -> float:
        return models.nearest_in_cone(
            scan.ranges,
            scan.angle_min,
            scan.angle_increment,
            scan.range_min,
            scan.range_max,
            self.params["scan_half_angle"],
        )

    def scan_fresh(self) -> bool:
        if self.last_scan_time is None:
            return False
        return seconds(self) - self.last_scan_time <= self.params["scan_timeout"]

    def verdict(self) -> str:
        """'no scan', 'blocked' or 'clear' for the current state."""
        if not self.scan_fresh():
            return "no scan"
        return "blocked" if self.nearest < self.params["safety_distance"] else "clear"

    def gate(self, cmd: Twist) -> Twist:
        verdict = self.verdict()
        out = Twist()
        if verdict == "no scan":
            return out
        out.linear.x, out.linear.y, out.linear.z = cmd.linear.x, cmd.linear.y, cmd.linear.z
        out.angular.x, out.angular.y, out.angular.z = cmd.angular.x, cmd.angular.y, cmd.angular.z
        if verdict == "blocked":
            out.linear.x = models.gate_forward(cmd.linear.x, self.nearest, self.params["safety_distance"])
        return out

    def _on_cmd(self, msg: Twist) -> None:
        self.last_input = msg
        self._send(msg)

    def _send(self, cmd: Twist) -> None:
        out = self.gate(cmd)
        if out != cmd:
            self.gated_count += 1
        self.cmd_pub.publish(out)

    def _on_scan(self, msg: LaserScan) -> None:
        self.last_scan, self.last_scan_time = msg, seconds(self)
        self.nearest = self._nearest(msg)
        self._react()

    def _react(self) -> None:
        """Re-send the last command at once when the verdict changed against it."""
        verdict = self.verdict()
        if verdict == self.last_verdict:
            return
        self.last_verdict = verdict
        if verdict != "clear" and self.last_input is not None and self.gate(self.last_input) != self.last_input:
            self._send(self.last_input)

    def diagnose(self) -> tuple[int, str, dict[str, Any]]:
        verdict = self.verdict()
        level = {"clear": OK, "blocked": WARN, "no scan": ERROR}[verdict]
        message = {
            "clear": "clear",
            "blocked": f"forward motion blocked: obstacle at {self.nearest:.2f} m",
            "no scan": "no recent scan",
        }[verdict]
        if self.sim_time_waiting():
            level, message = WARN, "waiting for /clock (use_sim_time)"
        age = math.inf if self.last_scan_time is None else seconds(self) - self.last_scan_time
        return (
            level,
            message,
            {
                "nearest_ahead": self.nearest,
                "scan_age_s": age,
                "safety_distance": self.params["safety_distance"],
                "gated_commands": self.gated_count,
            },
        )


def main(argv: list[str] | None = None) -> int:
    return main_for(SafetyNode, "safety", argv)


if __name__ == "__main__":
    raise SystemExit(main())
