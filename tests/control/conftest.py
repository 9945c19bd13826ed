"""Fixtures of the control-plane tests (helpers in control_helpers.py)."""

from __future__ import annotations

import pytest

from fleet.testing.isolation import reserve_domain_id
from tests.control.control_helpers import Cluster


@pytest.fixture(scope="module")
def domain_id():
    with reserve_domain_id() as reservation:
        yield reservation.domain_id


def start_two_agents(cluster: Cluster) -> Cluster:
    """Start the router and agents hostA and hostB, and wait until both agents are online."""
    cluster.start_router()
    cluster.start_agent("hostA")
    cluster.start_agent("hostB")
    cluster.wait_agents_online("hostA", "hostB")
    return cluster


@pytest.fixture(scope="module")
def cluster(tmp_path_factory, domain_id):
    """Router + agents hostA and hostB, shared by a module's tests (stopped at its end)."""
    cluster = Cluster(tmp_path_factory.mktemp("cluster"), domain_id)
    try:
        yield start_two_agents(cluster)
    finally:
        cluster.stop()


@pytest.fixture
def fresh_cluster(tmp_path, domain_id):
    """A cluster of this test alone, nothing started yet."""
    cluster = Cluster(tmp_path, domain_id)
    try:
        yield cluster
    finally:
        cluster.stop()


@pytest.fixture
def fresh_two_agents(fresh_cluster):
    """A router and agents hostA and hostB of this test alone (it may kill and restart them),
    both agents online."""
    return start_two_agents(fresh_cluster)


@pytest.fixture(scope="module")
def host_a(tmp_path_factory, domain_id):
    """A router and agent hostA of a module's tests, which run fleets/two_robots.yaml there
    (Cluster.two_robots_on_host_a)."""
    cluster = Cluster(tmp_path_factory.mktemp("host_a"), domain_id)
    try:
        cluster.start_router()
        cluster.start_agent("hostA")
        cluster.wait_agents_online("hostA")
        yield cluster
    finally:
        cluster.stop()
