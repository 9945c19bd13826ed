"""The environment of a fleet's ROS processes: one ROS domain, and how its participants meet.

Two ways, by whether the fleet has a discovery server (docs/multi-computer.md says why):

- With one (every fleet an agent runs): ROS_DISCOVERY_SERVER makes each participant a Fast DDS
  discovery client of the fleet's server, wherever the server's computer is.  Discovery is
  unicast and linear in participants; no multicast is needed.  The discovery range is left at
  SUBNET: LOCALHOST would confine the participant's locators to 127.0.0.1.
- Without one (`fleet run`, a node started by hand in a test): discovery range LOCALHOST,
  which keeps the process on this computer.

Transport: UDPv4 only.  Measured with the Jazzy wheels: with range LOCALHOST, rmw_fastrtps adds
Fast DDS's shared-memory transport whatever FASTDDS_BUILTIN_TRANSPORTS says (segments and port
mutexes appear in /dev/shm), and segments left by SIGKILLed participants can hang later
participants at creation.  With a discovery server and UDPv4, no /dev/shm file is created.
"""

from __future__ import annotations

import os

# The discovery server of domain d listens on 7400 + 250 d + 2 + slot: inside the domain's own
# block of RTPS ports (offsets 0 and 1 are its multicast ports, 10 + 2 i and 11 + 2 i participant
# i's), in the gap 2..9 RTPS leaves unused, so fleets on one computer (one domain each) never
# collide.  Slot 0 is the fleet's one server (`dds` transport); with `zenoh` every agent runs a
# server of its own on its loopback, and agents sharing a computer need distinct slots.
_PORT_BASE, _DOMAIN_GAIN, _SERVER_OFFSET, SERVER_SLOTS = 7400, 250, 2, 8


def domain_ports(domain_id: int) -> range:
    """The UDP ports of the domain's block: its participants' and its discovery servers'."""
    first = _PORT_BASE + _DOMAIN_GAIN * domain_id
    return range(first, first + _DOMAIN_GAIN)


def discovery_server_port(domain_id: int, slot: int = 0) -> int:
    return domain_ports(domain_id).start + _SERVER_OFFSET + slot % SERVER_SLOTS


def ros_environment(
    domain_id: int, base: dict[str, str] | None = None, discovery_server: str | None = None
) -> dict[str, str]:
    """An environment for ROS processes of one domain; `discovery_server` is "address:port"."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(domain_id)
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy, conflicts with the range
    env.pop("ROS_STATIC_PEERS", None)
    env.pop("ROS_SUPER_CLIENT", None)  # nodes are plain clients; tools that list the graph set it
    if discovery_server:
        env["ROS_DISCOVERY_SERVER"] = discovery_server
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    else:
        env.pop("ROS_DISCOVERY_SERVER", None)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
    env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
    env["PYTHONUNBUFFERED"] = "1"
    return env
