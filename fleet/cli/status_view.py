"""The fleet view as rich tables: agents, robots, one line per world (`fleet status`, `fleet deploy`)."""

from __future__ import annotations

import time


def print_view(view, out, agents: bool = True, nodes: bool = False) -> None:
    for table in view_tables(view, agents, nodes):
        out.print(table)


def view_tables(view, agents: bool = True, nodes: bool = False):
    """The tables of `view`; with `nodes`, one of its robots' nodes too (`fleet status ROBOT`)."""
    from rich.text import Text

    from fleet.cli.output import table as make_table

    tables = []
    if agents:
        table = make_table(
            "agent", "state", "up", "last seen", "host", "address", "cores", "backends", "fleets", title="Agents"
        )
        for row in view.agents:
            state = Text("online", style="green") if row.online else Text("offline", style="red")
            seen = "now" if row.online else (_ago(row.last_seen) if row.last_seen is not None else "never")
            table.add_row(
                row.name,
                state,
                _duration(row.uptime) if row.uptime is not None else "",
                seen,
                row.hostname,
                row.address,
                str(row.cores or ""),
                ", ".join(row.backends),
                ", ".join(row.fleets),
            )
        tables.append(table)
    several_fleets = len({row.fleet for row in view.robots}) > 1
    columns = ["robot", "agent", "state", "nodes", "restarts", "deployed", "pose x,y,yaw", "battery"]
    # Why a robot is not running, where one is not: the column only when there is something to say.
    reasons = any(row.reason and not row.error for row in view.robots)
    if reasons:
        columns.append("reason")
    table = make_table(*(["fleet", *columns] if several_fleets else columns), title="Robots")
    colours = {"running": "green", "starting": "yellow", "pending": "yellow", "degraded": "yellow"}
    for row in view.robots:
        colour = colours.get(row.state, "red")
        pose = f"{row.pose.get('x', 0):.2f},{row.pose.get('y', 0):.2f},{row.pose.get('yaw', 0):.2f}" if row.pose else ""
        battery = f"{row.battery * 100:.0f}%" if row.battery is not None else ""
        state = Text.assemble((row.state, colour), " (live overrides)" if row.overrides else "")
        cells = [
            row.name,
            row.agent,
            state,
            # An offline agent reports nothing, and a pending robot has no nodes yet: not 0/0.
            "-" if row.total == 0 and row.state in ("offline", "pending") else f"{row.running}/{row.total}",
            str(row.restarts),
            _generation_time(row.deployed_generation),
            pose,
            battery,
        ]
        if reasons:
            cells.append("" if row.error else row.reason)
        table.add_row(*([row.fleet, *cells] if several_fleets else cells))
    # An empty table reads as a failure to show: say there is nothing, as `kubectl get` does.
    tables.append(table if view.robots else Text("Robots: none deployed (`fleet deploy SPEC` runs a fleet)"))
    if nodes and any(row.nodes for row in view.robots):  # offline or pending robots report none
        tables.append(_nodes_table(view.robots, several_fleets))
    for world in view.worlds:
        tables.append(_world_line(world))
    for row in view.robots:
        if row.error:
            tables.append(Text(f"{row.fleet}/{row.name} on {row.agent}: {row.error}", style="red"))
    for fleet, topics in sorted(view.shared_topics.items()):
        for topic in topics:
            if topic["problem"]:
                tables.append(Text(f"{fleet}: {topic['problem']}", style="yellow"))
    return tables


def _nodes_table(robots, several_fleets: bool):
    """One row per node of each robot: its process as its agent's runner sees it."""
    from rich.text import Text

    from fleet.cli.output import table as make_table

    columns = ["robot", "node", "state", "pid", "restarts", "up", "last exit"]
    # Whether its agent sees each ROS node in the ROS graph (once the agent's watch reports).
    graph = any(node.get("in_graph") is not None for robot in robots for node in robot.nodes)
    if graph:
        columns.append("in ros graph")
    table = make_table(*(["fleet", *columns] if several_fleets else columns), title="Nodes")
    colours = {"running": "green", "starting": "yellow", "backoff": "yellow"}
    for robot in robots:
        for node in robot.nodes:
            uptime, code, seen = node.get("uptime"), node.get("exit_code"), node.get("in_graph")
            cells = [
                robot.name,
                node["name"],
                Text(node["state"], style=colours.get(node["state"], "red")),
                str(node.get("pid") or ""),
                str(node.get("restarts", 0)),
                _duration(uptime) if uptime is not None and node["state"] == "running" else "",
                "" if code is None else str(code),
            ]
            if graph:
                cells.append("" if seen is None else Text("yes", style="green") if seen else Text("no", style="red"))
            table.add_row(*([robot.fleet, *cells] if several_fleets else cells))
    return table


def _world_line(world):
    """One line per world: sim time, real-time factor, contacts (with the latest), problems."""
    from rich.text import Text

    from fleet.plan import WORLD_SILENT

    line = Text(
        f"world {world.fleet} on {world.agent}: t {world.sim_time:.1f} s, "
        f"RTF {world.real_time_factor:.2f}, {world.robots} robot{'' if world.robots == 1 else 's'}, "
    )
    count = world.contacts.get("count", 0)
    contacts = f"{count} contact" + ("" if count == 1 else "s")
    last = world.contacts.get("last") or []
    if last:
        contacts += f" (last {last[-1]['a']}-{last[-1]['b']} at {last[-1]['sim_time']:.1f} s)"
    line.append(contacts, style="yellow" if count else None)
    if world.age is not None and world.age > WORLD_SILENT:
        line.append(f"; no report for {world.age:.0f} s (not advancing)", style="red")
    if world.errors:
        more = f" (+{len(world.errors) - 1} more)" if len(world.errors) > 1 else ""
        line.append(f"; error: {world.errors[0]['message']}{more}", style="red")
    return line


def _ago(seconds: float) -> str:
    return f"{_duration(seconds)} ago"


def _duration(seconds: float) -> str:
    if seconds < 60:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _generation_time(generation: int) -> str:
    """Generations are deploy times in ns: show them as a time of day."""
    if generation <= 0:
        return ""
    return time.strftime("%H:%M:%S", time.localtime(generation / 1e9))
