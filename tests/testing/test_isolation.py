"""Which ROS domain ids tests reserve: every port their discovery servers may take lies below
Linux's ephemeral ports, where any DDS participant's sending sockets could hold it."""

from __future__ import annotations

from fleet.runtime.environment import SERVER_SLOTS, discovery_server_port
from fleet.testing import isolation


def ephemeral_start() -> int:
    return int(isolation._EPHEMERAL_PORTS.read_text().split()[0])


def test_every_test_domain_s_servers_lie_below_the_ephemeral_ports():
    domains = isolation._test_domains()
    assert len(domains) >= 8  # enough for suites running in parallel with themselves
    for domain in domains:
        assert all(discovery_server_port(domain, slot) < ephemeral_start() for slot in range(SERVER_SLOTS))


def test_the_next_domain_s_would_not():
    last = isolation._test_domains()[-1]
    assert discovery_server_port(last + 1, SERVER_SLOTS - 1) >= ephemeral_start()


def test_linux_s_default_range_gives_50_to_101(tmp_path, monkeypatch):
    ports = tmp_path / "ip_local_port_range"
    ports.write_text("32768\t60999\n")
    monkeypatch.setattr(isolation, "_EPHEMERAL_PORTS", ports)
    assert isolation._test_domains() == range(50, 102)
