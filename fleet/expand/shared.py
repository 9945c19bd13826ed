"""Topics a template declares shared: the checks of `share(...)` and what it records (pure).

A template calls `{{ share(topic, type, ...) }}` on a line of its own (it prints nothing) to say
that this robot's nodes publish or subscribe to `topic` and that it must reach the fleet's other
computers (the `zenoh` transport carries it between agents; with `dds` it crosses by itself).
A relative name resolves in the robot's namespace as ROS resolves it (`pose` -> `/robot1/pose`),
an absolute one is fleet-wide (`/fleet/announcements`).  QoS is the publishers': the receiving
agent's bridge republishes with it, so subscribers match as they would on one computer.
"""

from __future__ import annotations

import importlib.util
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from fleet.rules import MAX_TOPIC_NAME_LENGTH, resolve_topic_name, topic_name_problem

RELIABILITY = ("reliable", "best_effort")
DURABILITY = ("volatile", "transient_local")
ROBOT_ROLES = ("publishes", "subscribes", "both")  # what this robot's nodes do with the topic
MAX_DEPTH = 1000  # as a bridge route's (fleet.wire.protocol.TopicRoute)
MAX_TOKENS = 8  # tokens of a topic name a bridge route carries (fleet.wire.protocol.TopicRoute)
_MESSAGE_TYPE = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)/msg/([A-Za-z_][A-Za-z0-9_]*)")


class DeclarationError(ValueError):
    """A share(...) call the fleet cannot carry; the renderer locates it in the template."""


@dataclass(frozen=True)
class SharedTopic:
    name: str  # full name, resolved in the robot's namespace
    type: str  # pkg/msg/Name
    reliable: bool = True
    transient_local: bool = False
    depth: int = 10
    publishes: bool = True  # this robot's nodes publish it
    subscribes: bool = True  # this robot's nodes subscribe to it
    line: int | None = field(default=None, compare=False)  # of the template's share(...) call

    @property
    def route_fields(self) -> dict[str, Any]:
        """The fields of its bridge route (fleet.wire.protocol.TopicRoute)."""
        return {
            "name": self.name,
            "type": self.type,
            "reliable": self.reliable,
            "transient_local": self.transient_local,
            "depth": self.depth,
        }

    @property
    def qos(self) -> tuple[str, str, int]:
        """The QoS as written in a template, for messages."""
        return (RELIABILITY[not self.reliable], DURABILITY[self.transient_local], self.depth)


class SharedMark(str):
    """What share() returns: prints as nothing (fleet.expand.templating.yaml_literal)."""


def declare(
    topic: object,
    message_type: object,
    namespace: str,
    robot: object = "both",
    reliability: object = "reliable",
    durability: object = "volatile",
    depth: object = 10,
) -> SharedTopic:
    """Check one share(...) call of a template rendered for a robot in `namespace`."""
    if problem := topic_name_problem(topic):
        raise DeclarationError(f"share(): topic {problem}")
    assert isinstance(topic, str)
    name = resolve_topic_name(topic, namespace)
    if len(name) > MAX_TOPIC_NAME_LENGTH or name.count("/") > MAX_TOKENS:
        raise DeclarationError(
            f"share(): topic {name[:60]!r} is too long to carry: at most {MAX_TOKENS} tokens and "
            f"{MAX_TOPIC_NAME_LENGTH} characters"
        )
    if problem := message_type_problem(message_type):
        raise DeclarationError(f"share(): type {problem}")
    assert isinstance(message_type, str)
    for key, value, allowed in (
        ("robot", robot, ROBOT_ROLES),
        ("reliability", reliability, RELIABILITY),
        ("durability", durability, DURABILITY),
    ):
        if value not in allowed:
            raise DeclarationError(f"share(): {key} is one of {', '.join(allowed)}, got {value!r}")
    if isinstance(depth, bool) or not isinstance(depth, int) or not 1 <= depth <= MAX_DEPTH:
        raise DeclarationError(f"share(): depth is a whole number from 1 to {MAX_DEPTH}, got {depth!r}")
    return SharedTopic(
        name=name,
        type=message_type,
        reliable=reliability == "reliable",
        transient_local=durability == "transient_local",
        depth=depth,
        publishes=robot in ("publishes", "both"),
        subscribes=robot in ("subscribes", "both"),
    )


def message_type_problem(message_type: object) -> str | None:
    """Why `message_type` cannot be a shared topic's type, or None.  A message package installed
    here must have the message (a typo is caught at render); one that is not installed here may
    still be on the agents, which need it to carry the topic."""
    if not isinstance(message_type, str):
        return f"must be a string such as 'std_msgs/msg/String', not {type(message_type).__name__}"
    match = _MESSAGE_TYPE.fullmatch(message_type)
    if match is None:
        return f"{message_type!r} is not a message type: write package/msg/Name, e.g. 'geometry_msgs/msg/PoseStamped'"
    package, message = match.groups()
    try:
        spec = importlib.util.find_spec(package)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.submodule_search_locations:
        return None
    # rosidl_generator_py writes <package>/msg/_<snake_case name>.py for each message.
    module = re.sub(r"(?<=[a-z0-9])(?=[A-Z])|(?<=[A-Z])(?=[A-Z][a-z])", "_", message).lower()
    if not any((Path(folder) / "msg" / f"_{module}.py").is_file() for folder in spec.submodule_search_locations):
        return f"{message_type!r}: package {package} has no message {message}"
    return None


def merge(declared: list[SharedTopic]) -> list[SharedTopic]:
    """One robot's declarations, one per topic: the roles of repeated ones combined; the same
    topic with another type or QoS is an error."""
    by_name: dict[str, SharedTopic] = {}
    for topic in declared:
        known = by_name.get(topic.name)
        if known is None:
            by_name[topic.name] = topic
            continue
        if problem := conflict(known, topic):
            raise DeclarationError(f"share(): topic {topic.name} declared twice: {problem}")
        by_name[topic.name] = replace(
            known, publishes=known.publishes or topic.publishes, subscribes=known.subscribes or topic.subscribes
        )
    return list(by_name.values())


def conflict(first: SharedTopic, second: SharedTopic) -> str | None:
    """Why two declarations of one topic cannot both hold (every publisher and subscriber of a
    topic crosses with one type and one QoS), or None."""
    if first.type != second.type:
        return f"type {first.type} and {second.type}"
    if first.qos != second.qos:
        return "QoS {} and {}".format(*(" ".join(map(str, qos)) for qos in (first.qos, second.qos)))
    return None
