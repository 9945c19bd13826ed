"""What a failing fleet test shows: the status table, the last log lines of every node, the
world (sim time, poses, contacts, errors) and a snapshot picture of it.

Every part is gathered on its own: a router that is down costs the status table, not the logs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from fleet.testing.control_plane import ROUTER, agent_key

LOG_LINES = 15


def failure_sections(fleet, snapshot_path: str | Path | None = None) -> list[tuple[str, str]]:
    """(title, text) pairs for a test report; writes the snapshot when a path is given."""
    title = f"fleet {fleet.name}"
    return [
        (f"{title}: status", _guard(lambda: status_table(fleet))),
        (f"{title}: control plane", _guard(lambda: control_plane_text(fleet))),
        (f"{title}: node logs", _guard(lambda: node_logs_text(fleet))),
        (f"{title}: world", _guard(lambda: world_text(fleet, snapshot_path))),
    ]


def _guard(build) -> str:
    try:
        return build()
    except Exception as error:  # a report must never hide the failure it reports
        return f"(unavailable: {type(error).__name__}: {error})"


def status_table(fleet) -> str:
    """`fleet status` as plain text, one row per robot and one indented line per node."""
    view = fleet.status()
    lines = [f"domain {fleet.domain_id}, router {fleet.endpoint}, last deploy generation {fleet.generation}"]
    for agent in view.agents:
        lines.append(f"agent {agent.name}: {'online' if agent.online else 'OFFLINE'}")
    lines.append(
        f"{'robot':<12} {'agent':<10} {'state':<10} {'nodes':>5} {'restarts':>8}  {'pose (x, y, yaw)':<22} battery"
    )
    for row in view.robots:
        pose = f"{row.pose['x']:.2f}, {row.pose['y']:.2f}, {row.pose['yaw']:.2f}" if row.pose else ""
        battery = f"{row.battery * 100:.0f}%" if row.battery is not None else ""
        lines.append(
            f"{row.name:<12} {row.agent:<10} {row.state:<10} {row.running:>2}/{row.total:<2} {row.restarts:>8}  "
            f"{pose:<22} {battery}"
        )
        for node in row.nodes:
            exit_code = f" exit {node.get('exit_code')}" if node.get("exit_code") is not None else ""
            lines.append(
                f"    {node.get('name')}: {node.get('state')} pid {node.get('pid')} "
                f"restarts {node.get('restarts')}{exit_code}"
            )
        if row.error:
            lines.append(f"    error: {row.error}")
    problems = fleet.desired_state_problems()
    lines.append("desired state: " + ("reached" if not problems else "; ".join(problems)))
    return "\n".join(lines)


def control_plane_text(fleet) -> str:
    """Which router/agent processes run, and the last lines of each one's log."""
    running = fleet.control.running()
    parts = []
    for key in [ROUTER] + [agent_key(name) for name in fleet.agents()]:
        state = f"pid {running[key]}" if key in running else "NOT RUNNING"
        tail = fleet.control.log_tail(key, 8)
        parts.append(f"{key} ({state}):\n" + _indent(tail or "(empty log)"))
    return "\n".join(parts)


def node_logs_text(fleet, lines: int = LOG_LINES) -> str:
    parts = []
    for bundle in fleet.expansion.bundles:
        for process, text in fleet.logs(bundle.name, lines).items():
            parts.append(f"{bundle.name}/{process}:\n" + _indent("\n".join(text) or "(empty)"))
    # Only the last lines are shown here: say where the whole logs stay after the test.
    units = sorted({str(fleet.log_dir(bundle.name).parent.parent) for bundle in fleet.expansion.bundles})
    where = [f"whole logs (kept after the test): {directory}/<robot>/logs/" for directory in units]
    return "\n".join(["\n".join(parts) or "(no logs)", *where])


def world_text(fleet, snapshot_path: str | Path | None) -> str:
    world: dict[str, Any] | None = fleet.world()
    if world is None:
        return "(no world status)"
    lines = [f"sim time {world.get('sim_time')} s, real-time factor {world.get('real_time_factor')}"]
    for name, robot in sorted(world.get("robots", {}).items()):
        pose, velocity = robot.get("pose", {}), robot.get("velocity", {})
        lines.append(
            f"{name}: x {pose.get('x')} y {pose.get('y')} yaw {pose.get('yaw')}, "
            f"speed {velocity.get('linear')}, battery {robot.get('battery')}"
        )
    contacts = world.get("contacts", {})
    lines.append(f"contacts: {contacts.get('count', 0)}; last: {contacts.get('last', [])[-5:]}")
    if world.get("errors"):
        lines.append(f"errors: {world['errors']}")
    if snapshot_path is not None:
        from fleet.world.snapshot import draw_snapshot

        path = draw_snapshot(world, snapshot_path, title=f"fleet {fleet.name} at sim time {world.get('sim_time')} s")
        lines.append(f"snapshot: {path}")
    return "\n".join(lines)


def _indent(text: str) -> str:
    return "\n".join("    " + line for line in text.splitlines())
