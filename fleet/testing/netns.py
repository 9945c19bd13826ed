"""Computers for tests and benchmarks: Linux network namespaces on one LAN (a bridge).

Each Host is a network namespace with one veth link into a bridge that lives in the first
host's namespace (the "switch" is on the workstation; nothing touches the machine's own
network).  A host runs commands with `ip netns exec`, so they see only its interfaces: its
LAN address and its own loopback.  Cutting a host's link (`set_link(False)`) is a pulled cable.

Needs root or CAP_NET_ADMIN; `netns_problem()` says why it cannot run here.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import uuid
from dataclasses import dataclass


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, check=check)


def netns_problem() -> str | None:
    """None when this process can make network namespaces, else why not."""
    if shutil.which("ip") is None:
        return "the `ip` command (iproute2) is not installed"
    if os.geteuid() != 0:
        return "network namespaces need root or CAP_NET_ADMIN"
    name = f"fltprobe{uuid.uuid4().hex[:6]}"
    done = _ip("netns", "add", name, check=False)
    if done.returncode != 0:
        return f"cannot create a network namespace: {done.stderr.strip()}"
    _ip("netns", "del", name, check=False)
    return None


@dataclass
class Host:
    name: str  # our name for it ("sim", "rack_a")
    netns: str
    address: str
    link: str  # the veth end inside the bridge's namespace (the switch port)

    def command(self, *args: str) -> list[str]:
        return ["ip", "netns", "exec", self.netns, *args]


class Lan:
    """Hosts on one /24; the first host also holds the bridge."""

    def __init__(self, names: list[str], subnet: str = "10.88.0"):
        self.tag = uuid.uuid4().hex[:6]
        self.subnet = subnet
        self.hosts: dict[str, Host] = {}
        try:
            self._build(names)
        except BaseException:
            self.remove()
            raise

    def _build(self, names: list[str]) -> None:
        for index, name in enumerate(names):
            netns = f"flt{self.tag}{name}"
            _ip("netns", "add", netns)
            _ip("-n", netns, "link", "set", "lo", "up")
            self.hosts[name] = Host(name, netns, f"{self.subnet}.{index + 1}", link=f"s{self.tag}{index}")
        switch = self.hosts[names[0]].netns
        _ip("-n", switch, "link", "add", "br0", "type", "bridge")
        _ip("-n", switch, "link", "set", "br0", "up")
        for index, host in enumerate(self.hosts.values()):
            inside = f"h{self.tag}{index}"  # made in our namespace, then moved: names must be unique here
            _ip("link", "add", inside, "type", "veth", "peer", "name", host.link)
            _ip("link", "set", inside, "netns", host.netns)
            _ip("link", "set", host.link, "netns", switch)
            _ip("-n", host.netns, "link", "set", inside, "name", "eth0")
            _ip("-n", host.netns, "addr", "add", f"{host.address}/24", "dev", "eth0")
            _ip("-n", host.netns, "link", "set", "eth0", "up")
            _ip("-n", switch, "link", "set", host.link, "master", "br0")
            _ip("-n", switch, "link", "set", host.link, "up")
        self.switch = switch

    def set_link(self, name: str, up: bool) -> None:
        """Plug or pull the cable of host `name` (its switch port)."""
        _ip("-n", self.switch, "link", "set", self.hosts[name].link, "up" if up else "down")

    def remove(self) -> None:
        for host in self.hosts.values():
            _ip("netns", "del", host.netns, check=False)  # also removes its veth pairs
        self.hosts.clear()

    def __enter__(self) -> Lan:
        return self

    def __exit__(self, *exc) -> None:
        self.remove()
