"""What a rendered launch description declares: its arguments and its nodes.

Reads the YAML launch frontend structure just enough to know the nodes' full names (for the
per-namespace parameter sections) and the arguments (to check a robot's launch_args).  The
embedded runner (fleet.runtime) is the full reader; this one is pure and cheap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fleet.errors import Location, TemplateError

_ACTIONS = {
    "arg",
    "let",
    "set_env",
    "unset_env",
    "group",
    "push_ros_namespace",
    "node",
    "include",
    "executable",
    "log",
    "set_parameter",
    "set_remap",
    "timer",
    "declare_launch_argument",
}


@dataclass(frozen=True)
class NodeOutline:
    name: str
    package: str
    executable: str
    namespace: str  # absolute, as far as it is literal
    conditional: bool  # has if/unless

    @property
    def fqn(self) -> str:
        return f"{self.namespace.rstrip('/')}/{self.name}"


@dataclass(frozen=True)
class LaunchOutline:
    arguments: dict[str, str]  # name -> default as written
    nodes: tuple[NodeOutline, ...]


def outline(data: Any, where: Location) -> LaunchOutline:
    """Outline a parsed launch document; raises TemplateError when it is not one."""
    if not isinstance(data, dict) or set(data) != {"launch"} or not isinstance(data["launch"], list):
        raise TemplateError("a launch template must render to a mapping with one key 'launch' holding a list", where)
    arguments: dict[str, str] = {}
    nodes: list[NodeOutline] = []
    _walk(data["launch"], "/", arguments, nodes, where, top=True)
    names = [node.fqn for node in nodes if not node.conditional]
    duplicates = {name for name in names if names.count(name) > 1}
    if duplicates:
        raise TemplateError(f"two nodes would have the same name: {', '.join(sorted(duplicates))}", where)
    return LaunchOutline(arguments=arguments, nodes=tuple(nodes))


def _walk(
    actions: list[Any], namespace: str, arguments: dict[str, str], nodes: list[NodeOutline], where: Location, top: bool
) -> None:
    for action in actions:
        if not isinstance(action, dict) or len(action) != 1:
            raise TemplateError(f"each launch action must be a mapping with one key, got {action!r:.60}", where)
        ((kind, body),) = action.items()
        if kind not in _ACTIONS:
            raise TemplateError(f"unknown launch action {kind!r}", where)
        if kind == "group":
            children = body if isinstance(body, list) else (body or {}).get("actions", body)
            if not isinstance(children, list):
                raise TemplateError("a group holds a list of actions", where)
            _walk(children, namespace, arguments, nodes, where, top=False)
        elif kind == "push_ros_namespace":
            pushed = _literal(body, "namespace", where)
            namespace = pushed if pushed.startswith("/") else f"{namespace.rstrip('/')}/{pushed}"
        elif kind == "arg":
            name = _literal(body, "name", where)
            if top:
                arguments[name] = str(body.get("default", ""))
        elif kind == "node":
            name = _literal(body, "name", where)
            node_namespace = body.get("namespace")
            if node_namespace is None:
                full = namespace
            elif str(node_namespace).startswith("/"):
                full = str(node_namespace)
            else:
                full = f"{namespace.rstrip('/')}/{node_namespace}"
            nodes.append(
                NodeOutline(
                    name=name,
                    package=str(body.get("pkg", "")),
                    executable=str(body.get("exec", "")),
                    namespace=full,
                    conditional="if" in body or "unless" in body,
                )
            )


def _literal(body: Any, key: str, where: Location) -> str:
    if not isinstance(body, dict) or key not in body:
        raise TemplateError(f"launch action is missing {key!r}", where)
    value = str(body[key])
    if "$(" in value:
        raise TemplateError(f"{key} {value!r} must be literal in a fleet template (no substitutions)", where)
    return value
