"""The node executables as real processes: start-up checks, parameter services, signals,
composite."""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytestmark = pytest.mark.integration

rclpy = pytest.importorskip("rclpy")

from geometry_msgs.msg import Twist  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rcl_interfaces.srv import GetParameters, SetParameters  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from sensor_msgs.msg import BatteryState, LaserScan  # noqa: E402

PYTHON = sys.executable


class NodeProcess:
    """`python -m fleet.nodes.<module> args...`, output kept in a file for the assertions."""

    def __init__(self, module: str, args: list[str], env: dict, log: Path):
        self.log = log
        self._out = open(log, "w")  # noqa: SIM115 (the process writes to it until wait() closes it)
        self.proc = subprocess.Popen(
            [PYTHON, "-m", f"fleet.nodes.{module}", *args],
            env=env,
            stdout=self._out,
            stderr=subprocess.STDOUT,
        )

    def wait(self, timeout: float = 20.0) -> int:
        try:
            return self.proc.wait(timeout=timeout)
        finally:
            self._out.close()

    def stop(self, sig: int = signal.SIGINT) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            return self.wait(timeout=10.0)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
            raise

    @property
    def output(self) -> str:
        return self.log.read_text()


@pytest.fixture
def start(ros_env, tmp_path):
    started: list[NodeProcess] = []

    def _start(module: str, *args: str) -> NodeProcess:
        process = NodeProcess(module, list(args), ros_env, tmp_path / f"{module}-{len(started)}.log")
        started.append(process)
        return process

    yield _start
    for process in started:
        if process.proc.poll() is None:
            process.proc.kill()
            process.wait()


def write(path: Path, text: str) -> str:
    path.write_text(text)
    return str(path)


def set_parameter(ros, node: str, name: str, value):
    client = ros.probe.create_client(SetParameters, f"{node}/set_parameters")
    request = SetParameters.Request(parameters=[Parameter(name, value=value).to_parameter_msg()])
    return ros.call(client, request, timeout=15.0).results[0]


def get_parameters(ros, node: str, *names: str) -> list:
    client = ros.probe.create_client(GetParameters, f"{node}/get_parameters")
    values = ros.call(client, GetParameters.Request(names=list(names)), timeout=15.0).values
    plain = [Parameter.from_parameter_msg(_msg(name, v)).value for name, v in zip(names, values, strict=True)]
    return [list(v) if hasattr(v, "typecode") else v for v in plain]  # array.array -> list


def _msg(name, value):
    from rcl_interfaces.msg import Parameter as ParameterMsg

    return ParameterMsg(name=name, value=value)


@pytest.mark.parametrize(
    "module, params, reason",
    [
        (
            "controller",
            "/robot1/controller:\n  ros__parameters:\n    max_speed: 7.0\n",
            "parameter 'max_speed' = 7.0 is out of range 0.0 .. 5.0",
        ),
        (
            "battery",
            "/**:\n  ros__parameters:\n    critical_threshold: 0.5\n",
            "critical_threshold (0.5) must be <= low_threshold (0.2)",
        ),
        (
            "safety",
            "/robot1/safety:\n  ros__parameters:\n    scan_timeout: 'soon'\n",
            "parameter 'scan_timeout' must be of type double, got string 'soon'",
        ),
    ],
)
def test_invalid_parameter_file_exits_non_zero_with_the_reason(start, tmp_path, module, params, reason):
    params_file = write(tmp_path / "params.yaml", params)
    node = start(
        module,
        "--ros-args",
        "-r",
        "__ns:=/robot1",
        "-r",
        f"__node:={module}",
        "--params-file",
        params_file,
    )
    assert node.wait() == 2
    assert f"{module}: error: /robot1/{module}: {reason}" in node.output


def test_composite_refuses_a_bad_group(start, tmp_path):
    node = start(
        "composite",
        "--fleet-node",
        "controller",
        "--ros-args",
        "-r",
        "__ns:=/robot1",
        "--fleet-node",
        "safety",
        "--ros-args",
        "-r",
        "__ns:=/robot1",
        "-p",
        "safety_distance:=-1.0",
    )
    assert node.wait() == 2
    assert "/robot1/safety: parameter 'safety_distance' = -1.0 is out of range" in node.output
    usage = start("composite", "--fleet-node", "world")
    assert usage.wait() == 2 and "unknown node executable 'world'" in usage.output


def test_live_parameter_changes_through_the_parameter_service(ros, start):
    node = start("controller", "--ros-args", "-r", "__ns:=/robot1", "-r", "__node:=controller")
    refused = set_parameter(ros, "/robot1/controller", "max_speed", 9.0)
    assert not refused.successful
    assert "max_speed out of range" in refused.reason
    odd = set_parameter(ros, "/robot1/controller", "waypoints", [1.0, 2.0, 3.0])
    assert not odd.successful and "even length" in odd.reason
    assert set_parameter(ros, "/robot1/controller", "max_speed", 0.8).successful
    assert get_parameters(ros, "/robot1/controller", "max_speed", "waypoints") == [
        0.8,
        [2.0, 0.0, 2.0, 2.0, 0.0, 2.0, 0.0, 0.0],
    ]
    assert node.stop(signal.SIGTERM) == 0, node.output


def test_composite_hosts_one_robot_with_per_node_arguments(ros, start, tmp_path):
    params_file = write(
        tmp_path / "robot1.params.yaml",
        """
/robot1/driver:
  ros__parameters:
    waypoints: [3.0, 0.0]
    max_speed: 0.4
/robot1/battery:
  ros__parameters:
    capacity: 50.0
    publish_rate: 5.0
/robot1/safety:
  ros__parameters:
    safety_distance: 0.6
""",
    )
    common = ["-r", "__ns:=/robot1", "--params-file", params_file]
    composite = start(
        "composite",
        # The controller renamed to "driver" (proving __node applies per node), its output remapped.
        "--fleet-node",
        "controller",
        "--ros-args",
        "-r",
        "__node:=driver",
        *common,
        "-r",
        "cmd_vel:=cmd_vel_nav",
        "-p",
        "goal_tolerance:=0.3",
        "--log-level",
        "warn",
        "--fleet-node",
        "battery",
        "--ros-args",
        "-r",
        "__node:=battery",
        *common,
        "-p",
        "idle_draw:=7.0",
        "--fleet-node",
        "safety",
        "--ros-args",
        "-r",
        "__node:=safety",
        *common,
        "-r",
        "cmd_vel_in:=cmd_vel_nav",
        "-r",
        "cmd_vel_out:=cmd_vel",
    )
    # Each node has its own name, parameters from the file and from its own -p only.
    assert get_parameters(ros, "/robot1/driver", "waypoints", "max_speed", "goal_tolerance") == [
        [3.0, 0.0],
        0.4,
        0.3,
    ]
    assert get_parameters(ros, "/robot1/battery", "capacity", "publish_rate", "idle_draw") == [
        50.0,
        5.0,
        7.0,
    ]
    assert get_parameters(ros, "/robot1/safety", "safety_distance", "scan_timeout") == [0.6, 1.0]
    names = set(ros.probe.get_node_names_and_namespaces())
    assert {("driver", "/robot1"), ("battery", "/robot1"), ("safety", "/robot1")} <= names

    # The chain works as with separate processes:
    # odom -> driver -> cmd_vel_nav -> safety -> cmd_vel.
    odom_pub = ros.probe.create_publisher(Odometry, "/robot1/odom", 10)
    scan_pub = ros.probe.create_publisher(LaserScan, "/robot1/scan", 10)
    nav = ros.latest(Twist, "/robot1/cmd_vel_nav")
    out = ros.latest(Twist, "/robot1/cmd_vel")
    batteries = ros.latest(BatteryState, "/robot1/battery")
    scan = LaserScan(
        angle_min=-math.pi,
        angle_increment=math.pi / 180,
        range_min=0.1,
        range_max=8.0,
        ranges=[5.0] * 360,
    )
    odom = Odometry()
    odom.pose.pose.orientation.w = 1.0

    def driving():
        odom_pub.publish(odom)
        scan_pub.publish(scan)
        return nav and out and out[-1].linear.x > 0.0

    ros.spin_until(lambda: (ros.spin_for(0.05), driving())[1], timeout=15.0)
    assert nav[-1].linear.x == pytest.approx(0.4) and out[-1].linear.x == pytest.approx(0.4)
    ros.spin_until(lambda: batteries)
    assert batteries[-1].power_supply_health == BatteryState.POWER_SUPPLY_HEALTH_GOOD

    refused = set_parameter(ros, "/robot1/battery", "low_threshold", 0.01)
    assert not refused.successful and "critical_threshold (0.05) must be <= low_threshold (0.01)" in refused.reason
    started = time.monotonic()
    assert composite.stop(signal.SIGINT) == 0
    assert time.monotonic() - started < 5.0
