"""Finding a fleet, its robots and its ROS graph from one status query."""

from __future__ import annotations

import time

from fleet.client.control_client import ControlClient
from fleet.errors import BadRequest, ControlError, FleetError, did_you_mean
from fleet.plan.view import FleetView, build_view, known_fleets
from fleet.wire import protocol as p

LISTED_ROBOTS = 10  # an error line names at most this many robots


def fleet_status(client: ControlClient, fleet: str | None) -> tuple[list[p.StatusReply], list[p.RegistryReply]]:
    """client.status(fleet); BadRequest when `fleet` names a fleet no agent serves and the router
    has no record of: a mistyped name would otherwise show as an empty fleet, all running."""
    statuses, registries = client.status(fleet)
    if fleet is None or fleet in known_fleets(statuses, registries):
        return statuses, registries
    known = known_fleets(*client.status(None))
    listed = f"fleets: {', '.join(known)}" if known else "none is deployed"
    raise BadRequest(f"no fleet named {fleet!r} here ({listed})")


def locate_robot(client: ControlClient, robot: str, fleet: str | None) -> tuple[str, str]:
    """(fleet, agent) running `robot`, from one status query."""
    return robot_place(build_view(*client.status(fleet), time.time()), robot, fleet)


def robot_place(view: FleetView, robot: str, fleet: str | None) -> tuple[str, str]:
    """(fleet, agent) running `robot` in `view`; BadRequest for a robot it does not have."""
    found = view.find_robot(robot, fleet)
    if not found:
        raise _not_deployed(view, robot, fleet)
    rows = [row for row in found if row.state not in ("pending", "offline")]
    if not rows:
        states = ", ".join(f"{row.state} in fleet {row.fleet}" for row in found)
        raise ControlError(f"robot {robot!r} is not running ({states})")
    if len(rows) > 1:
        raise FleetError(f"robot {robot!r} exists in fleets {', '.join(r.fleet for r in rows)}: pick one with --fleet")
    return rows[0].fleet, rows[0].agent


def robots_named(view: FleetView, robots: list[str], fleet: str | None) -> FleetView:
    """`view` cut down to `robots` (`fleet status ROBOT...`); BadRequest for one it does not have."""
    for robot in robots:
        if not view.find_robot(robot, fleet):
            raise _not_deployed(view, robot, fleet)
    return view.of_robots(robots)


def _not_deployed(view: FleetView, robot: str, fleet: str | None) -> BadRequest:
    where = f" in fleet {fleet}" if fleet else ""
    return BadRequest(f"no robot named {robot!r} is deployed{where}{_robots_hint(view, robot, fleet)}")


def _robots_hint(view: FleetView, robot: str, fleet: str | None) -> str:
    """The robots deployed, when a line can hold them; in a large fleet the closest name."""
    names = sorted({row.name for row in view.robots if fleet is None or row.fleet == fleet})
    if len(names) <= LISTED_ROBOTS:
        return f" (robots: {', '.join(names)})" if names else ""
    return did_you_mean(robot, names)


def tool_environment(view: FleetView, fleet: str | None, agent: str | None) -> dict[str, str]:
    """ROS_DOMAIN_ID, ROS_DISCOVERY_SERVER (the fleet's server; with the zenoh transport the one of
    `agent`, whose computer this must be) and ROS_SUPER_CLIENT: a plain client would see only the
    topics it uses itself.  One clear error when the fleet or the server is ambiguous (pure)."""
    fleets = sorted(view.domain_ids)
    if fleet is None:
        if len(fleets) != 1:
            raise FleetError(
                "no fleet is deployed"
                if not fleets
                else f"several fleets run ({', '.join(fleets)}): pick one with --fleet"
            )
        fleet = fleets[0]
    if fleet not in view.domain_ids:
        raise ControlError(f"fleet {fleet} is not deployed (see `fleet status`)")
    servers = {server["agent"]: server["server"] for server in view.discovery.get(fleet, [])}
    if agent is not None:
        if agent not in servers:
            raise FleetError(
                f"agent {agent} runs no discovery server of fleet {fleet} "
                f"(those that do: {', '.join(sorted(servers)) or 'none'})"
            )
        server = servers[agent]
    elif len(servers) == 1:
        server = next(iter(servers.values()))
    elif not servers:
        raise ControlError(f"no discovery server of fleet {fleet} answers (is its world's agent online?)")
    else:
        raise FleetError(
            f"fleet {fleet} uses the zenoh transport: every computer has its own DDS; "
            f"pick the agent on this one with --agent ({', '.join(sorted(servers))})"
        )
    return {
        "ROS_DOMAIN_ID": str(view.domain_ids[fleet]),
        "ROS_DISCOVERY_SERVER": server,
        "ROS_SUPER_CLIENT": "TRUE",
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
    }
