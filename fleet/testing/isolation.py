"""Isolation of concurrent fleets and test runs on one machine.

A ROS domain id is reserved by holding an exclusive lock on a file named after it, so two test
sessions running in parallel never share a domain, and a crashed holder frees its domain (the
kernel drops the lock).  Zenoh ports come from the kernel (bind to port 0).
"""

from __future__ import annotations

import fcntl
import random
import socket
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from fleet.runtime.environment import SERVER_SLOTS, discovery_server_port, ros_environment

__all__ = [
    "DomainReservation",
    "discovery_served",
    "free_tcp_port",
    "reserve_domain_id",
    "ros_environment",
    "with_domain_id",
]

# Fast DDS maps domain id d to a block of UDP ports (fleet.runtime.environment.domain_ports),
# the fleet's discovery servers among them.  Ports in Linux's ephemeral range are where every
# DDS participant also binds sockets for sending: a fleet of one test could find its discovery
# server's port taken by another test's process.  So tests use ids from 50 (clear of 0, the
# default everyone uses, and of the low ids people pick) up to the last whose servers' ports lie
# below that range: 50..101 with Linux's default range, 32768..60999.
_FIRST_TEST_DOMAIN = 50
_EPHEMERAL_PORTS = Path("/proc/sys/net/ipv4/ip_local_port_range")
_DEFAULT_EPHEMERAL_START = 32768


def _test_domains() -> range:
    try:
        ephemeral_start = int(_EPHEMERAL_PORTS.read_text().split()[0])
    except (OSError, ValueError, IndexError):
        ephemeral_start = _DEFAULT_EPHEMERAL_START
    last = _FIRST_TEST_DOMAIN
    while discovery_server_port(last + 1, SERVER_SLOTS - 1) < ephemeral_start:
        last += 1
    return range(_FIRST_TEST_DOMAIN, last + 1)


_DOMAIN_RANGE = _test_domains()
_LOCK_DIR = Path(tempfile.gettempdir()) / "fleet-domain-locks"


class DomainReservation:
    """An exclusively held ROS_DOMAIN_ID; release() (or process exit) frees it."""

    def __init__(self, domain_id: int, lock_file):
        self.domain_id = domain_id
        self._lock_file = lock_file

    def release(self) -> None:
        if self._lock_file is not None:
            self._lock_file.close()
            self._lock_file = None

    def __enter__(self) -> DomainReservation:
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def reserve_domain_id() -> DomainReservation:
    _LOCK_DIR.mkdir(parents=True, exist_ok=True)
    candidates = list(_DOMAIN_RANGE)
    random.shuffle(candidates)
    for domain_id in candidates:
        lock_file = open(_LOCK_DIR / f"{domain_id}.lock", "a")  # noqa: SIM115 (held open: it is the lock)
        try:
            fcntl.flock(lock_file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            lock_file.close()
            continue
        return DomainReservation(domain_id, lock_file)
    raise RuntimeError(f"no free ROS domain id in {_DOMAIN_RANGE.start}..{_DOMAIN_RANGE.stop - 1}")


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """A TCP port the kernel says is free now (small race window; callers retry on bind failure)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((host, 0))
        return sock.getsockname()[1]


def with_domain_id(spec, domain_id: int):
    """A copy of a FleetSpec whose nodes use `domain_id` (pure: the spec is not changed).

    Tests override the spec's ros.domain_id with a reserved one so two runs of the same spec on
    one machine never see each other's topics."""
    return spec.model_copy(update={"ros": spec.ros.model_copy(update={"domain_id": domain_id})})


@contextmanager
def discovery_served(domain_id: int, log_file: Path) -> Iterator[dict[str, str]]:
    """The environment of ROS processes of `domain_id` that find each other through a Fast DDS
    discovery server of their own (running while in the `with`), as a deployed fleet's do: UDP
    only.  With LOCALHOST discovery instead, every participant maps shared memory in /dev/shm,
    and one killed by a test leaves its segments behind."""
    from fleet.dataplane.discovery import discovery_server
    from fleet.runtime.environment import discovery_server_port

    address = f"127.0.0.1:{discovery_server_port(domain_id)}"
    server = discovery_server(address, ros_environment(domain_id), log_file)
    server.keep_running()
    try:
        yield ros_environment(domain_id, discovery_server=address)
    finally:
        server.stop()
