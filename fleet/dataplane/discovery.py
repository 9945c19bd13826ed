"""Running a fleet's Fast DDS discovery server (`fast-discovery-server`, from the ROS wheels), and
the address an agent reports for it.  Where it runs is planned by fleet.plan.discovery.
"""

from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

from fleet.files import write_atomic
from fleet.runtime.processes import ServiceProcess

SERVER_PROGRAM = "fast-discovery-server"  # ships in the ROS wheels (package ros-fastrtps)

# A Fast DDS client keeps a server that went silent until the server's lease runs out.  A server
# killed without a word (SIGKILL, a crash: no "unregister" message) and started again within
# that lease is taken by the clients for the old one, which knew them: they never announce
# themselves to it again, so no participant started since ever finds them.  Robots on another
# computer were cut off for good from a world whose agent was killed and started again.  So the
# server announces a lease of its own, and one that died is started again only after it has run
# out at every client (they then look for a server again, and find the new one).
SERVER_LEASE = 10.0  # seconds (Fast DDS's default is 20)
SERVER_ANNOUNCEMENT = 2.0  # how often it asserts that lease: 5 times per lease, as lost packets go
RESTART_AFTER = SERVER_LEASE + 1.0

_PROFILE = f"""<?xml version="1.0" encoding="UTF-8" ?>
<!-- Written by fleet: the lease of the fleet's DDS discovery server (fleet.dataplane.discovery). -->
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <participant profile_name="fleet_discovery_server" is_default_profile="true">
      <rtps>
        <builtin>
          <discovery_config>
            <discoveryProtocol>SERVER</discoveryProtocol>
            <leaseDuration><sec>{SERVER_LEASE:.0f}</sec><nanosec>0</nanosec></leaseDuration>
            <leaseAnnouncement><sec>{SERVER_ANNOUNCEMENT:.0f}</sec><nanosec>0</nanosec></leaseAnnouncement>
          </discovery_config>
        </builtin>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def server_program() -> Path | None:
    """The discovery server executable next to this interpreter, else on PATH."""
    found = shutil.which(
        SERVER_PROGRAM, path=os.pathsep.join([str(Path(sys.prefix) / "bin"), os.environ.get("PATH", "")])
    )
    return Path(found) if found else None


def _library_path(env: dict[str, str]) -> str:
    # The ROS wheels set LD_LIBRARY_PATH for Python (their .pth hook re-executes it); the server,
    # a plain executable, also needs the prefix's lib/ where libfastrtps lives.
    parts = [part for part in env.get("LD_LIBRARY_PATH", "").split(os.pathsep) if part]
    return os.pathsep.join([*parts, str(Path(sys.prefix) / "lib")])


def server_command(server: str, profile: Path) -> list[str]:
    """The command line of a discovery server listening on `server` ("address:port"), with its
    settings in `profile` (written here)."""
    program = server_program()
    if program is None:
        raise FileNotFoundError(f"{SERVER_PROGRAM} not found (it comes with the ros-jazzy wheels)")
    profile.parent.mkdir(parents=True, exist_ok=True)
    write_atomic(profile, _PROFILE)
    address, _, port = server.rpartition(":")
    return [str(program), "--server-id", "0", "--udp-address", address, "--udp-port", port, "--xml-file", str(profile)]


def server_environment(env: dict[str, str]) -> dict[str, str]:
    """`env` with the library path the server executable needs."""
    return {**env, "LD_LIBRARY_PATH": _library_path(env)}


def discovery_server(
    server: str, env: dict[str, str], log_file: Path, down_since: float | None = None
) -> ServiceProcess:
    """The discovery server as a service (its profile beside `log_file`), started again
    RESTART_AFTER seconds after it died.  down_since: the monotonic time from which a server of
    an earlier run of the caller may have died without a word (started no sooner than
    RESTART_AFTER after it)."""
    profile = log_file.with_suffix(".xml")
    command = server_command(server, profile)
    return ServiceProcess(command, server_environment(env), log_file, RESTART_AFTER, down_since)


WILDCARDS = {"0.0.0.0", "::"}  # a listen endpoint on every interface of this computer
ANYWHERE = "203.0.113.1"  # TEST-NET-3: a route probe towards it takes the default route


def address_towards(endpoints: list[str]) -> str:
    """This computer's IPv4 address on the route to the first reachable Zenoh endpoint (what the
    other computers of the fleet see it as); 127.0.0.1 when the router is on this computer.

    An agent in the process of a router listening on every interface (`fleet up --listen
    tcp/0.0.0.0:7447`, so that agents of other computers join it) is given that wildcard: it
    reports the address of this computer's default route, or else its first address that is not
    loopback; 127.0.0.1 would send the other computers' nodes to their own loopback.
    A UDP socket's connect only picks the route: nothing is sent."""
    for endpoint in endpoints:
        _, _, locator = endpoint.partition("/")
        host = locator.rsplit(":", 1)[0].strip("[]")
        if host in WILDCARDS:
            return _route_address(ANYWHERE) or _interface_address() or "127.0.0.1"
        if address := _route_address(host):
            return address
    return "127.0.0.1"


def _route_address(host: str) -> str | None:
    import socket

    try:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.connect((host, 9))
            return str(probe.getsockname()[0])
    except OSError:
        return None


def _interface_address() -> str | None:
    """The first IPv4 address, not loopback, of an interface that is up (a computer whose network
    has no default route, as on an isolated LAN)."""
    import socket

    import psutil

    up = {name for name, stats in psutil.net_if_stats().items() if stats.isup}
    for name, addresses in psutil.net_if_addrs().items():
        for address in addresses:
            if name in up and address.family == socket.AF_INET and not address.address.startswith("127."):
                return str(address.address)
    return None
