"""The embedded runner with the real fleet_nodes nodes, checked from rclpy in an isolated domain."""

from __future__ import annotations

import pytest

from fleet.runtime.supervisor import LaunchSession
from fleet.testing.ros import RosProbe

pytestmark = pytest.mark.integration

LAUNCH = """
launch:
- arg: {name: speed, default: '0.8'}
- group:
  - push_ros_namespace: {namespace: robot1}
  - node:
      pkg: fleet_nodes
      exec: controller
      name: controller
      param:
      - {from: $(dirname)/robot1.params.yaml}
      - {name: max_speed, value: $(var speed)}
  - node:
      pkg: fleet_nodes
      exec: battery
      name: battery
      param:
      - {from: $(dirname)/robot1.params.yaml}
- node: {pkg: fleet_nodes, exec: battery, name: battery, namespace: robot2}
"""
PARAMS = """
/robot1/controller:
  ros__parameters:
    max_speed: 0.3
    goal_tolerance: 0.2
/robot1/battery:
  ros__parameters:
    capacity: 42.0
"""
EXPECTED_NODES = {"/robot1/controller", "/robot1/battery", "/robot2/battery"}


@pytest.fixture
def probe(ros_env):
    with RosProbe() as probe:
        yield probe


@pytest.mark.parametrize("isolation", ["process", "robot"])
def test_namespaced_fleet_nodes_with_parameters(ros_env, probe, tmp_path, isolation):
    (tmp_path / "robot1.params.yaml").write_text(PARAMS)
    path = tmp_path / "robot1.launch.yaml"
    path.write_text(LAUNCH)
    session = LaunchSession(
        path, {"speed": "1.25"}, env=ros_env, log_dir=tmp_path / "logs", isolation=isolation, backend="embedded"
    )
    with session:
        probe.wait_for_nodes(EXPECTED_NODES)
        statuses = session.status()
        assert {status.state for status in statuses} == {"running"}, [
            (status.process, session.tail(status.process)) for status in statuses
        ]
        # Robot isolation: every fleet_nodes controller/battery/safety of the launch file shares
        # one process (a rendered launch file holds one robot).
        expected_processes = 3 if isolation == "process" else 1
        assert len({status.pid for status in statuses}) == expected_processes
        # The inline parameter comes after the file, so it wins; the file sets the rest.
        assert probe.get_parameters("/robot1/controller", ["max_speed", "goal_tolerance"]) == [1.25, 0.2]
        assert probe.get_parameters("/robot1/battery", ["capacity"]) == [42.0]
        assert probe.get_parameters("/robot2/battery", ["capacity"]) == [100.0]
    assert {status.state for status in session.status()} == {"stopped"}
    # Stopped by SIGINT, the nodes shut down by themselves (no SIGTERM/SIGKILL needed).
    assert {status.exit_code for status in session.status()} <= {0, -2}
