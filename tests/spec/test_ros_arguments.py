"""A node's ROS arguments (its `ros_args`, and its `args` after a --ros-args) are refused where
rcl or rclpy refuses them: the node would not start, so the launch interpreter (and render,
deploy's check) refuses them first.  The answers below are rclpy's (Jazzy); checked against
rclpy when present."""

from __future__ import annotations

import pytest

from fleet.rules import ros_arguments_problem

# (command line, rclpy starts with it)
COMMAND_LINES = [
    (["--ros-args", "--log-level", "info"], True),
    (["--ros-args", "--log-level", "DEBUG"], True),
    (["--ros-args", "--log-level", "Warn"], True),
    (["--ros-args", "--log-level", "unset"], True),
    (["--ros-args", "--log-level", "rclpy:=debug"], True),
    (["--ros-args", "--log-level", "a-b.c:=fatal"], True),
    (["--ros-args", "--log-level", "bogus"], False),
    (["--ros-args", "--log-level", "warning"], False),
    (["--ros-args", "--log-level", "a:=bogus"], False),
    (["--ros-args", "--log-level", ":=info"], False),
    (["--ros-args", "--log-level", ""], False),
    (["--ros-args", "--log-level", "a\nb"], False),
    (["--ros-args", "--log-level"], False),
    (["--ros-args", "-r", "a:=b", "--remap", "c:=d"], True),
    (["--ros-args", "-r", "a-b:=c"], False),
    (["--ros-args", "-r", "ab"], False),
    (["--ros-args", "-p", "a:=1", "--param", "b.c:=[1, 2]", "-p", "node:d:=x"], True),
    (["--ros-args", "-p", "a"], False),
    (["--ros-args", "-p", "a:="], False),
    (["--ros-args", "-e", "/fleet/r1"], True),
    (["--ros-args", "--enclave", "r1"], False),
    (["--ros-args", "--log-file-name", "x", "--disable-rosout-logs", "--enable-stdout-logs"], True),
    (["--ros-args", "--disable-external-lib-logs"], True),
    (["--ros-args", "--log-config-file", "/tmp/x.conf"], False),
    (["--ros-args", "--bogus"], False),
    (["--ros-args", "-r", "a:=b", "extra"], False),
    (["x", "--bogus", "--ros-args", "-r", "a:=b", "--", "--bogus"], True),  # only ROS arguments are rcl's
    (["--ros-args", "--log-level", "info", "--ros-args", "--log-level", "bogus"], False),
]


@pytest.mark.parametrize(("arguments", "starts"), COMMAND_LINES)
def test_ros_arguments_refused_where_rclpy_refuses_them(arguments, starts):
    problem = ros_arguments_problem(arguments)
    assert (problem is None) == starts, problem


def test_the_answers_are_rclpys():
    rclpy = pytest.importorskip("rclpy")
    from rclpy.context import Context

    for arguments, starts in COMMAND_LINES:
        context = Context()
        try:
            rclpy.init(args=arguments, context=context)
        except Exception:
            started = False
        else:
            started = True
            rclpy.shutdown(context=context)
        assert started == starts, arguments
