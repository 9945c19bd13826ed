"""What a deploy would run, as data (--json) and as rich tables: used by render and deploy --dry-run."""

from __future__ import annotations

from typing import Any

from fleet.expand import Expansion
from fleet.expand.parameters import Setting
from fleet.spec.rcl_types import value_text


def plan_data(expansion: Expansion) -> dict[str, Any]:
    spec = expansion.spec
    world = expansion.bundle("world")
    robots = []
    for plan in expansion.robots:
        bundle = expansion.bundle(plan.name)
        assert bundle is not None  # every robot has its bundle
        effective = plan.parameters
        parameters: dict[str, dict[str, Any]] = {}
        for (node, name), settings in effective.history.items():
            parameters.setdefault(node, {})[name] = {"value": settings[-1].value, "from": settings[-1].layer}
        robots.append(
            {
                "name": plan.name,
                "agent": plan.agent,
                "namespace": plan.namespace,
                "template": plan.template,
                "isolation": plan.isolation,
                "simulated": plan.simulated,  # as fleet status --json says it
                "model": plan.model.model_dump(),
                "pose": plan.pose,
                "launch_args": plan.launch_args,
                "nodes": [
                    {
                        "name": node.name,
                        "fqn": node.fqn,
                        "package": node.package,
                        "executable": node.executable,
                        "conditional": node.conditional,
                    }
                    for node in plan.outline.nodes
                ],
                "parameters": parameters,
                "digest": bundle.digest,
            }
        )
    return {
        "fleet": spec.fleet,
        "domain_id": spec.ros.domain_id,
        "use_sim_time": spec.ros.use_sim_time,
        "agents": {
            name: {"description": agent.description, "units": [b.name for b in expansion.for_agent(name)]}
            for name, agent in spec.agents.items()
        },
        "world": None
        if world is None or spec.world is None  # a world bundle comes from the spec's world
        else {"agent": world.agent, "obstacles": len(spec.world.obstacles), "digest": world.digest},
        "robots": robots,
        "warnings": expansion.warnings,
    }


def print_plan(expansion: Expansion, console) -> None:
    from fleet.cli.output import labelled, table

    data = plan_data(expansion)
    world = (
        f"world on agent {data['world']['agent']} ({data['world']['obstacles']} obstacles)"
        if data["world"]
        else "no world"
    )
    settings = f"ROS_DOMAIN_ID={data['domain_id']}  use_sim_time={str(data['use_sim_time']).lower()}  {world}"
    console.print(labelled(f"fleet {data['fleet']}", "bold", f" {settings}"))
    robots = table("robot", "agent", "namespace", "template", "nodes", "model", "pose x,y,yaw", title="Robots")
    for robot in data["robots"]:
        nodes = ", ".join(node["name"] + ("?" if node["conditional"] else "") for node in robot["nodes"])
        pose = robot["pose"]
        # A model and a pose are the world's: a robot it does not host has neither.
        hosted = data["world"] is not None and robot["simulated"]
        robots.add_row(
            robot["name"],
            robot["agent"],
            robot["namespace"],
            robot["template"],
            nodes,
            robot["model"]["type"] if hosted else "real" if data["world"] else "",
            f"{pose['x']:.2f},{pose['y']:.2f},{pose['yaw']:.2f}" if hosted else "",
        )
    console.print(robots)
    if any(node["conditional"] for robot in data["robots"] for node in robot["nodes"]):
        console.print(labelled("? = started only when its launch condition holds (e.g. enable_safety)", "dim"))
    parameters = table("robot", "node", "parameter", "value", "from", title="Effective parameters")
    for robot in data["robots"]:
        for node, values in robot["parameters"].items():
            for name, entry in values.items():
                style = "" if entry["from"] == "template" else "bold"
                parameters.add_row(robot["name"], node, name, value_text(entry["value"]), entry["from"], style=style)
    console.print(parameters)


def explain_data(expansion: Expansion, key: str) -> dict[str, Any]:
    from fleet.errors import Location, SpecError

    robot_name, _, rest = key.partition(".")
    node, _, name = rest.partition(".")
    plan = expansion.robot(robot_name)
    if plan is None or not node or not name:
        raise SpecError(
            f"expected ROBOT.NODE.PARAMETER of a robot in the spec "
            f"(robots: {', '.join(r.name for r in expansion.robots)})",
            Location(f"--explain {key}"),
        )
    settings: list[Setting] = plan.parameters.explain(node, name)
    if inline := plan.inline_setting(node, name):
        settings.append(inline)
    if not settings:
        known = sorted({n for (nd, n) in plan.parameters.history if nd == node})
        raise SpecError(
            f"{robot_name}.{node} has no parameter {name!r} in any layer"
            + (f" (parameters: {', '.join(known)})" if known else f" (no node {node!r})"),
            Location(f"--explain {key}"),
        )
    return {
        "parameter": key,
        "value": settings[-1].value,
        "layers": [
            {"layer": s.layer, "value": s.value, "source": s.source, "effective": i == len(settings) - 1}
            for i, s in enumerate(settings)
        ],
    }


def print_explain(data: dict[str, Any], console) -> None:
    from fleet.cli.output import table as make_table

    layers = make_table("layer", "value", "source", "", title=f"{data['parameter']} = {_explained(data['value'])}")
    for layer in data["layers"]:
        layers.add_row(
            layer["layer"],
            _explained(layer["value"]),
            layer["source"],
            "effective" if layer["effective"] else "overridden",
            style="bold" if layer["effective"] else "dim",
        )
    console.print(layers)


def _explained(value: Any) -> str:
    # None: the launch file starts the node without the parameter file (RobotPlan.inline_setting)
    return "(the node's own default)" if value is None else value_text(value)
