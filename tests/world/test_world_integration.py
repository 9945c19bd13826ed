"""The world as a real process with real rclpy in an isolated domain: cmd_vel -> odom, /clock,
contacts in the status file, robots joining and leaving through world.yaml."""

import json
import math
import subprocess
import sys
import threading
import time
from functools import partial
from pathlib import Path

import pytest

from fleet.testing.poll import poll

pytestmark = pytest.mark.integration

WORLD = """\
fleet: it
obstacles:
- {{name: wall, type: box, position: [6.0, 0.0], size: [0.2, 4.0, 1.0]}}
robots:
- {{name: robot1, pose: {{x: 0.0, y: 0.0}}, cmd_timeout: 0.5}}
- {{name: robot2, pose: {{x: 2.0, y: 0.0}}}}
{extra}"""


def read_status(path: Path):
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return None


class Listener:
    """A test-side rclpy node: latest odom per robot, clock count, a cmd_vel publisher."""

    def __init__(self):
        import rclpy
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from rosgraph_msgs.msg import Clock

        self.rclpy = rclpy
        self.Twist = Twist
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("world_test", context=self.context)
        self.odom: dict[str, object] = {}
        self.clock_count = 0
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.BEST_EFFORT)
        for name in ("robot1", "robot2", "robot3"):
            self.node.create_subscription(Odometry, f"/{name}/odom", partial(self.odom.__setitem__, name), qos)
        self.node.create_subscription(Clock, "/clock", self._on_clock, qos)
        self.cmd = self.node.create_publisher(Twist, "/robot1/cmd_vel", 10)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self):
        while not self._stop.is_set():
            self.executor.spin_once(timeout_sec=0.05)

    def _on_clock(self, msg):
        self.clock_count += 1

    def drive(self, linear):
        msg = self.Twist()
        msg.linear.x = linear
        self.cmd.publish(msg)

    def close(self):
        # The spinning thread ends first: shutting the executor down under a callback it runs
        # makes that thread fail (rclpy's guard condition is gone, or the node's handle).
        self._stop.set()
        self.thread.join()
        self.executor.shutdown()
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)


@pytest.fixture
def world(start_world):
    config, status, proc = start_world(WORLD.format(extra=""), "--as-fast-as-possible")
    listener = Listener()
    try:
        yield config, status, listener, proc
    finally:
        listener.close()


def test_world_drives_reports_contacts_and_hosts_joining_robots(world):
    config, status_file, ros, proc = world
    poll(lambda: "robot1" in ros.odom and "robot2" in ros.odom, timeout=20, interval=0.05, what="odom from both robots")
    poll(lambda: ros.clock_count, until=lambda count: count > 10, timeout=5, interval=0.05, what="/clock")

    # Drive robot1 backwards, away from everything: its odom moves, robot2's does not.  (Not
    # forwards: as fast as possible the world can cover the 1.6 m to robot2 before our odom
    # subscription has caught up.)
    def robot1_moved():
        ros.drive(-0.5)
        return ros.odom["robot1"].pose.pose.position.x < -0.3

    poll(robot1_moved, timeout=10, interval=0.05, what="robot1's odom to advance")
    robot2 = ros.odom["robot2"]
    assert abs(robot2.pose.pose.position.x) < 0.01 and abs(robot2.twist.twist.linear.x) < 1e-3
    assert ros.odom["robot1"].header.frame_id == "robot1/odom"
    assert ros.odom["robot1"].child_frame_id == "robot1/base_link"

    # Keep driving into robot2: one contact in the status file, and no passing through.
    def contact_reported():
        ros.drive(0.5)
        status = read_status(status_file)
        return status if status and status["contacts"]["count"] >= 1 else None

    status = poll(contact_reported, timeout=20, interval=0.05, what="a contact in the status file")
    first = status["contacts"]["last"][0]
    assert (first["a"], first["b"], first["kind"]) == ("robot1", "robot2", "robot-robot")
    for _ in range(10):  # robot1 keeps pushing (robot2 may slide aside): they never overlap
        ros.drive(0.5)
        status = read_status(status_file) or status
        one, two = status["robots"]["robot1"]["pose"], status["robots"]["robot2"]["pose"]
        assert math.hypot(one["x"] - two["x"], one["y"] - two["y"]) > 0.37  # radii 0.2 + 0.2
        time.sleep(0.05)

    # Without commands robot1 stops once its last one is older than cmd_timeout.
    poll(
        lambda: ros.odom["robot1"].twist.twist.linear.x,
        until=lambda speed: abs(speed) < 1e-3,
        timeout=10,
        interval=0.05,
        what="robot1 to stop after cmd_timeout",
    )

    # A robot joins by rewriting world.yaml, then leaves.
    config.write_text(WORLD.format(extra="- {name: robot3, pose: {x: 0.0, y: -3.0}}\n"))
    poll(
        lambda: "robot3" in (read_status(status_file) or {}).get("robots", {}),
        timeout=10,
        interval=0.05,
        what="robot3 in the status",
    )
    poll(lambda: "robot3" in ros.odom, timeout=10, interval=0.05, what="odom from robot3")
    assert proc.poll() is None
    config.write_text(WORLD.format(extra=""))
    poll(
        lambda: "robot3" not in (read_status(status_file) or {}).get("robots", {"robot3": 1}),
        timeout=10,
        interval=0.05,
        what="robot3 to leave the status",
    )
    poll(
        lambda: ros.node.count_publishers("/robot3/odom"),
        until=lambda count: count == 0,
        timeout=10,
        interval=0.05,
        what="robot3's publishers to go away",
    )
    assert set(read_status(status_file)["robots"]) == {"robot1", "robot2"}
    assert read_status(status_file)["errors"] == []


@pytest.mark.parametrize(
    "text, problem",
    [
        ("robots:\n- {name: robot1, model: {type: tank}}\n", "unknown model type 'tank'"),
        # Both once ran: a world that hung after its first step, deaf to Ctrl-C (the lidar cutting
        # the crate into 1 m pieces), and one that slept 1000 s between steps.
        (
            "obstacles:\n- {name: crate, type: box, position: [2.5, 1.5], size: [1.0e+300, 0.5, 0.5]}\n"
            "robots:\n- {name: robot1}\n",
            "'size' must be at most 10000 m",
        ),
        ("physics_rate: 0.001\nrobots:\n- {name: robot1}\n", "'physics_rate' must be at least 50"),
    ],
)
def test_invalid_world_exits_2_with_one_line(tmp_path, ros_env, text, problem):
    config = tmp_path / "world.yaml"
    config.write_text(text)
    done = subprocess.run(
        [sys.executable, "-m", "fleet.nodes.world", "--config", str(config)],
        env=ros_env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"fleet: error: {config}:") and problem in lines[0], lines


def test_the_world_reports_each_robots_data_flow(ros_env):
    """What `running` rests on, as the world's ROS process reports it: the age of a robot's last
    cmd_vel (None before the first, never negative or infinite: the status file must stay JSON)
    and its odom's subscribers; a robot keeps them when another joins ahead of it."""
    import numpy as np
    from geometry_msgs.msg import Twist
    from nav_msgs.msg import Odometry

    from fleet.testing.ros import RosProbe
    from fleet.world.description import RobotSpec
    from fleet.world.ros_process import RosProcess

    r1, r0 = RobotSpec(name="r1", namespace="/r1"), RobotSpec(name="r0", namespace="/r0")
    bridge = RosProcess([])
    try:
        bridge.set_robots(1, [r1], [])
        assert bridge.inputs().link(0) == {"cmd_age": None, "odom_subscribers": 0}
        with RosProbe() as probe:
            probe.subscribe("/r1/odom", Odometry)

            def link_seen():
                probe.publish("/r1/cmd_vel", Twist())
                return bridge.inputs().link(0)

            poll(
                link_seen,
                until=lambda link: link["cmd_age"] is not None and link["odom_subscribers"],
                timeout=20,
                interval=0.1,
                pause=probe.spin,
                what="a command and an odom subscriber seen by the world's ROS process",
            )
            cmd_age = bridge.inputs().link(0)["cmd_age"]
            assert cmd_age is not None and 0.0 <= cmd_age < 5.0
        bridge.set_robots(2, [r0, r1], [])  # r1 moves to row 1 and keeps what it had
        inputs = bridge.inputs()
        assert inputs.generation == 2 and inputs.link(0)["cmd_age"] is None
        assert inputs.link(1)["cmd_age"] is not None and inputs.link(1)["odom_subscribers"]
        bridge.hold(np.array([[0.0, 0.0], [0.5, 0.0]]))  # a benchmark's never-expiring command
        inputs = poll(
            bridge.inputs,
            until=lambda inputs: inputs.commands[1, 0] == 0.5,
            timeout=10,
            interval=0.05,
            what="the held command",
        )
        json.dumps(inputs.link(1), allow_nan=False)
        assert inputs.link(1)["cmd_age"] == 0.0
        assert inputs.live_commands(np.array([0.5, 0.5]), sim_time=1e9).tolist() == [[0.0, 0.0], [0.5, 0.0]]
    finally:
        bridge.close()
    assert not bridge.ok()


def test_the_world_exits_1_when_its_ros_process_dies(start_world):
    """Without its ROS process the world cannot publish: it exits 1 with one line, so that its
    supervisor restarts both, instead of stepping on with no one hearing it."""
    import psutil

    config, status, proc = start_world(WORLD.format(extra=""), "--as-fast-as-possible")
    poll(lambda: read_status(status), timeout=30, interval=0.1, what="the world's status file")
    children = psutil.Process(proc.pid).children()
    (ros_side,) = [child for child in children if "fleet.world.ros_process" in child.cmdline()]
    ros_side.kill()
    assert proc.wait(timeout=20) == 1
    log = (config.parent / "world.log").read_text()
    assert "fleet: error: the world's ROS process exited" in log and "Traceback" not in log, log


def test_the_world_s_ros_process_dies_with_the_world(start_world):
    """A SIGKILLed world (as when its supervisor dies) takes its ROS process along at once: the
    kernel kills it, even when it could not read the closed socket (here: stopped)."""
    import signal

    import psutil

    _config, status, proc = start_world(WORLD.format(extra=""), "--as-fast-as-possible")
    poll(lambda: read_status(status), timeout=30, interval=0.1, what="the world's status file")
    children = psutil.Process(proc.pid).children()
    (ros_side,) = [child for child in children if "fleet.world.ros_process" in child.cmdline()]
    ros_side.send_signal(signal.SIGSTOP)
    proc.kill()
    proc.wait(timeout=10)
    _gone, alive = psutil.wait_procs([ros_side], timeout=10)
    if alive:
        ros_side.kill()  # clean up, then fail
    assert not alive, "the world's ROS process outlived the SIGKILLed world"
