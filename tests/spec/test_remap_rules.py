"""Remap rules are refused exactly where rcl refuses them: a rule rcl cannot parse stops the node
at start ("Couldn't parse remap rule"), so the launch interpreter (and render, deploy's check)
must refuse it first.  The answers below are rclpy's (Jazzy); checked against rclpy when present."""

from __future__ import annotations

import pytest

from fleet.rules import remap_problem, ros_name_problem

# (from, to, rcl accepts)
RULES = [
    ("odom", '/"t1"/odom', False),
    ("cmd_vel", "shadow cmd vel!", False),
    ("cmd-vel", "x", False),
    ("a", "b", True),
    ("~/a", "b", True),
    ("a", "~/b", True),
    ("/a", "/b/c", True),
    ("~/a/b", "~/c/d", True),
    ("_", "_", True),
    ("a_", "A1", True),
    ("__node", "x", True),
    ("__name", "x", True),
    ("__node", "2x", False),
    ("__node", "a/b", False),
    ("__node", "a__b", False),
    ("__ns", "/x", True),
    ("__ns", "/", True),
    ("__ns", "/a/", True),
    ("__ns", "x", False),
    ("__ns", "/2a", False),
    ("__ns", "/a//b", False),
    ("2a", "b", False),
    ("a", "2b", False),
    ("a/2b", "c", False),
    ("a", "{node}/b", False),
    ("{node}", "b", False),
    ("a__b", "c", False),
    ("a", "b__c", False),
    ("__a", "b", False),
    ("__params", "x", False),
    ("n:a", "b", True),
    ("n:__ns", "/x", True),
    ("n:~/a", "b", True),
    ("2n:a", "b", False),
    ("n-x:a", "b", False),
    ("rostopic://a", "b", True),
    ("rosservice://a", "b", True),
    ("rostopic://~/a", "b", True),
    ("rostopic://__ns", "/x", False),
    ("a", "rostopic://b", False),
    ("a", "b/", False),
    ("a/", "b", False),
    ("/", "b", False),
    ("a", "/", False),
    ("a//b", "c", False),
    ("*", "b", False),
    ("a/**", "b", False),
    ("a", "\\1", False),
    ("~", "b", False),
    ("a", "~", False),
    ("a", "~b", False),
    ("a", "", False),
    ("", "b", False),
    ("a", "b:=c", False),
    ("ä", "b", False),
    ("a", "x" * 300, True),
]


@pytest.mark.parametrize(("source", "target", "accepted"), RULES)
def test_remap_rules_refused_where_rcl_refuses_them(source, target, accepted):
    problem = remap_problem(source, target)
    assert (problem is None) == accepted, problem


@pytest.mark.parametrize("name", ["a", "A1", "_", "_a", "a_", "a_b_c", "a__b", "__a", "a__", "2a", "a-b"])
def test_a_valid_robot_or_node_name_is_one_rcl_takes_in_its_remap_rules(name):
    """launch_ros passes a node's name and namespace as `-r __node:=name` and `-r __ns:=/ns`."""
    valid = ros_name_problem(name) is None
    assert valid == (remap_problem("__node", name) is None) == (remap_problem("__ns", f"/{name}") is None), name


def test_the_answers_are_rcls():
    rclpy = pytest.importorskip("rclpy")
    from rclpy.context import Context

    for source, target, accepted in RULES:
        context = Context()
        try:
            rclpy.init(args=["--ros-args", "-r", f"{source}:={target}"], context=context)
        except Exception:
            parsed = False
        else:
            parsed = True
            rclpy.shutdown(context=context)
        assert parsed == accepted, (source, target)
