"""Fixtures of the fleet.nodes tests (the harness is ros_harness.Ros)."""

from __future__ import annotations

import pytest

from tests.nodes.ros_harness import Ros


@pytest.fixture
def ros(ros_env):
    """A fresh rclpy context confined to this test's ROS domain (ros_env set os.environ)."""
    harness = Ros()
    try:
        yield harness
    finally:
        harness.close()
