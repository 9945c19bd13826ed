"""Name rules.  Robot names become ROS namespaces, agent and fleet names become Zenoh key parts."""

from __future__ import annotations

import re

# ROS 2 name tokens (rmw_validate_node_name / namespace tokens): letters, digits, underscores,
# not starting with a digit.
_ROS_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
# Zenoh key chunks must not contain / * $ ? # and we keep them boring on purpose.
_KEY_CHUNK = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
MAX_NAME_LENGTH = 63


def ros_name_problem(name: object) -> str | None:
    """Why `name` is not a valid ROS node/robot name, or None if it is."""
    if not isinstance(name, str):
        return f"must be a string, not {type(name).__name__}"
    if not name:
        return "must not be empty"
    if len(name) > MAX_NAME_LENGTH:
        return f"is longer than {MAX_NAME_LENGTH} characters"
    if not _ROS_TOKEN.fullmatch(name):
        if name[0].isdigit():
            return f"{name!r} is not a valid ROS name: it must not start with a digit"
        return f"{name!r} is not a valid ROS name: use letters, digits and underscores only"
    return None


def namespace_problem(namespace: object) -> str | None:
    """Why `namespace` is not a valid absolute ROS namespace like /site_a/robot1, or None."""
    if not isinstance(namespace, str):
        return f"must be a string, not {type(namespace).__name__}"
    if not namespace.startswith("/") or namespace == "/":
        return f"{namespace!r} must be an absolute namespace such as '/robot1'"
    for token in namespace[1:].split("/"):
        problem = ros_name_problem(token)
        if problem:
            return f"namespace {namespace!r}: token {problem}"
    return None


def key_name_problem(name: object) -> str | None:
    """Why `name` cannot be a fleet or agent name (used in Zenoh keys and file names), or None."""
    if not isinstance(name, str):
        return f"must be a string, not {type(name).__name__}"
    if not _KEY_CHUNK.fullmatch(name) or len(name) > MAX_NAME_LENGTH:
        return (
            f"{name!r} is not a valid name: use letters, digits, '_', '-', '.' (not first), at most {MAX_NAME_LENGTH}"
        )
    return None
