"""What a deploy would change: the desired state of an Expansion against the fleet as it runs (pure)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from fleet.plan.view import FleetView
from fleet.wire import protocol as p

if TYPE_CHECKING:
    from fleet.expand.expansion import Expansion


@dataclass
class DiffRow:
    robot: str
    agent: str
    change: str  # start, stop, restart, hot-update, move, unchanged
    detail: str = ""


def diff(expansion: Expansion, view: FleetView) -> list[DiffRow]:
    """What a deploy of `expansion` would change, robot by robot (live overrides shown as drift)."""
    current = {row.name: row for row in view.robots_of(expansion.fleet)}
    rows = []
    for bundle in expansion.bundles:
        running = current.pop(bundle.name, None)
        hot = p.hot_digest(dict(bundle.files), list(bundle.hot_files))
        if running is None:
            rows.append(DiffRow(bundle.name, bundle.agent, "start"))
        elif not running.digest:  # only the registry's plan knows it: its agent never ran it, or is away
            detail = f"agent {running.agent} offline: running state unknown" if running.state == "offline" else ""
            rows.append(DiffRow(bundle.name, bundle.agent, "start" if not detail else "unknown", detail))
        elif running.agent != bundle.agent:
            rows.append(DiffRow(bundle.name, bundle.agent, "move", f"from agent {running.agent}"))
        elif running.digest != bundle.digest:
            rows.append(DiffRow(bundle.name, bundle.agent, "restart", "launch description or parameters changed"))
        elif running.hot_digest != hot:
            rows.append(DiffRow(bundle.name, bundle.agent, "hot-update", ", ".join(sorted(bundle.hot_files))))
        elif running.state == "offline":
            rows.append(DiffRow(bundle.name, bundle.agent, "unchanged", "agent offline"))
        else:
            rows.append(DiffRow(bundle.name, bundle.agent, "unchanged"))
        if running is not None and running.overrides and rows[-1].change in ("unchanged", "hot-update"):
            drift = "; ".join(
                f"{node} {name}={value!r}"
                for node, values in sorted(running.overrides.items())
                for name, value in sorted(values.items())
            )
            rows[-1].detail = (rows[-1].detail + "; " if rows[-1].detail else "") + f"live overrides kept: {drift}"
    for name, row in sorted(current.items()):
        rows.append(DiffRow(name, row.agent, "stop", "not in the spec any more"))
    return rows
