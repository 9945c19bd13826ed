"""Shared fixtures: every test gets its own ROS domain and leaves no process behind."""

from __future__ import annotations

import os
import uuid

import pytest

from fleet.testing.isolation import discovery_served, reserve_domain_id
from fleet.testing.processes import MARKER_VARIABLE, processes_marked, terminate


@pytest.fixture(autouse=True, scope="session")
def _ros_log_dir(tmp_path_factory):
    """rcl writes a log file per node process; keep them in pytest's temp dir, not ~/.ros/log."""
    os.environ.setdefault("ROS_LOG_DIR", str(tmp_path_factory.mktemp("ros-log")))


@pytest.fixture(autouse=True)
def _reap_processes(request):
    """Mark every process this test starts; kill the ones still alive when it ends."""
    marker = f"{uuid.uuid4().hex[:12]}-{request.node.name[:40]}"
    previous = os.environ.get(MARKER_VARIABLE)
    os.environ[MARKER_VARIABLE] = marker
    try:
        yield
    finally:
        if previous is None:
            os.environ.pop(MARKER_VARIABLE, None)
        else:
            os.environ[MARKER_VARIABLE] = previous
        leftovers = processes_marked(marker)
        if leftovers:
            terminate(leftovers)


@pytest.fixture
def ros_domain():
    """A ROS domain id reserved for this test only."""
    with reserve_domain_id() as reservation:
        yield reservation.domain_id


@pytest.fixture
def ros_env(ros_domain, monkeypatch, tmp_path_factory):
    """Environment (also applied to os.environ) of this test's own ROS domain, whose participants
    find each other through a discovery server of the test's own, as a deployed fleet's do.

    Why a server here too: Fast DDS keeps the discovery server a process first saw in
    ROS_DISCOVERY_SERVER for its later participants even once the variable is gone (measured),
    so in a test process where a fleet test made a discovery client, a later LOCALHOST
    participant would look for that server and find nobody."""
    with discovery_served(ros_domain, tmp_path_factory.mktemp("discovery") / "server.log") as env:
        for key in (
            "ROS_DOMAIN_ID",
            "ROS_AUTOMATIC_DISCOVERY_RANGE",
            "RMW_IMPLEMENTATION",
            "FASTDDS_BUILTIN_TRANSPORTS",
            "ROS_DISCOVERY_SERVER",
        ):
            monkeypatch.setenv(key, env[key])
        monkeypatch.delenv("ROS_LOCALHOST_ONLY", raising=False)
        yield env
