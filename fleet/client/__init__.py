"""The control client: how the CLI, the dashboard and the test harness talk to a fleet's router
and agents (deploy, down, restart, status, logs, parameters), and start or stop the local daemon.

The plan (what to send) comes from fleet.plan, the messages from fleet.wire.
"""

from fleet.client.control_client import ControlClient, connect
from fleet.client.deployment import Outcome, Restart, check_domain, deploy, down, restart, visible_statuses
from fleet.client.robots import fleet_status, locate_robot, tool_environment

__all__ = [
    "ControlClient",
    "Outcome",
    "Restart",
    "check_domain",
    "connect",
    "deploy",
    "down",
    "fleet_status",
    "locate_robot",
    "restart",
    "tool_environment",
    "visible_statuses",
]
