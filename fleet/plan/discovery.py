"""Where a fleet's Fast DDS discovery server runs (pure): the plan a deploy sends its agents.

Every ROS participant of a fleet is a discovery client of one server (ROS_DISCOVERY_SERVER,
see fleet.runtime.environment): participants on any computer find each other through it by
unicast, with discovery traffic linear in participants.  One agent of the fleet runs it: the
agent running the world (it is up whenever the fleet is of any use), else the first agent by
name.  Its address is the one that agent reports (`fleet agent --address`, or the address it
reaches the router from), its port follows from the fleet's domain id.  A deploy made while no
agent of the fleet is online names the host without an address: the agents find it later
(fleet.server.agent).  Running the server is fleet.dataplane.discovery's.
"""

from __future__ import annotations

import hashlib
import ipaddress
from collections.abc import Mapping
from dataclasses import dataclass, field

from fleet.runtime.environment import SERVER_SLOTS, discovery_server_port


@dataclass(frozen=True)
class DiscoveryPlan:
    host: str | None  # agent running the server; None: the fleet has no agent
    server: str | None  # "address:port"; None: the host's address is not known yet (it is offline)
    note: str = ""  # why the choice is not the usual one, for the person deploying
    # The `zenoh` transport: every agent's own server on its loopback (see local_servers)
    local: Mapping[str, str] = field(default_factory=dict)


def plan_discovery(
    world_agent: str | None,
    agents: list[str],
    addresses: dict[str, str],
    domain_id: int,
    hostnames: Mapping[str, str] | None = None,
) -> DiscoveryPlan:
    """Which agent runs the fleet's discovery server (pure).

    `agents`: the agents the fleet places units on; `addresses`: online agents -> address;
    `hostnames`: agents -> the name of their computer, where known."""
    port = discovery_server_port(domain_id)
    preferred = world_agent or (sorted(agents)[0] if agents else None)
    host = preferred if preferred is not None and addresses.get(preferred) else None
    note = ""
    if host is None and (host := next((agent for agent in sorted(agents) if addresses.get(agent)), None)):
        note = f"agent {preferred} is offline: agent {host} runs the DDS discovery server"
    if host is not None:
        server = f"{addresses[host]}:{port}"
        if unreachable := _loopback_for_others(host, addresses, agents, hostnames or {}):
            note = f"{note}; {unreachable}" if note else unreachable
        return DiscoveryPlan(host, server, note)
    if preferred is None:
        return DiscoveryPlan(None, None)
    # Its address is not known yet: the host serves at the address it reports once up, and the
    # other agents ask it for that address (fleet.server.agent).
    return DiscoveryPlan(
        preferred,
        None,
        f"no agent of the fleet is online: agent {preferred} runs its DDS discovery server "
        "when it comes online, and the robots of other agents wait for it to reach across computers",
    )


def _loopback_for_others(
    host: str, addresses: Mapping[str, str], agents: list[str], hostnames: Mapping[str, str]
) -> str:
    """Why agents on other computers cannot reach a server at a loopback address, or "".  An agent
    reports 127.0.0.1 when it reaches the router through loopback (router and agent on one
    computer) or was told `--address 127.0.0.1`.  Another agent is on another computer when its
    computer's name differs, or when it reports an address that is not loopback: it reached the
    router over the network (robot computers made from one image often share a name)."""
    address = addresses[host]
    if not _is_loopback(address):
        return ""
    here = hostnames.get(host)
    elsewhere = sorted(
        agent
        for agent in agents
        if agent != host
        and ((here and hostnames.get(agent, here) != here) or not _is_loopback(addresses.get(agent, address)))
    )
    if not elsewhere:
        return ""
    return (
        f"agent {host} runs the DDS discovery server at {address}, a loopback address: the robots of "
        f"{', '.join(elsewhere)} on other computers cannot reach it. Start agent {host} with "
        "--address set to its address on the robots' network (or --connect to the router's address on it)"
    )


def _is_loopback(address: str) -> bool:
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:
        return address == "localhost"


def local_servers(agents: list[str], domain_id: int, hostnames: Mapping[str, str] | None = None) -> dict[str, str]:
    """The `zenoh` transport: each agent's own discovery server on its loopback (pure).  DDS then
    stays on each computer and the bridges carry what crosses.

    An agent's slot follows from its name, not from the other agents: a server that moves
    restarts every robot of its agent, and adding a computer must not restart the world.  Only
    agents on one computer (`hostnames`; agents of unknown hostname count as one computer) need
    different slots: of two that clash, the later by name takes the next free one."""
    hostnames = hostnames or {}
    taken: dict[str, set[int]] = {}
    servers = {}
    for agent in sorted(agents):
        used = taken.setdefault(hostnames.get(agent, ""), set())
        slot = int.from_bytes(hashlib.sha256(agent.encode()).digest()[:4], "big") % SERVER_SLOTS
        while slot in used and len(used) < SERVER_SLOTS:
            slot = (slot + 1) % SERVER_SLOTS
        used.add(slot)
        servers[agent] = f"127.0.0.1:{discovery_server_port(domain_id, slot)}"
    return servers
