"""The plan (pure): what should run where (one desired state per agent, from an Expansion), what
runs where now (the fleet view, from status replies), and the difference between the two."""

from fleet.plan.desired import (
    discovery_for,
    domain_clash,
    held_generation,
    new_generation,
    plan_record,
    requests_for,
    with_planned_agents,
)
from fleet.plan.diff import DiffRow, diff
from fleet.plan.view import WORLD_SILENT, FleetView, RobotRow, build_view, known_fleets, locate_world

__all__ = [
    "WORLD_SILENT",
    "DiffRow",
    "FleetView",
    "RobotRow",
    "build_view",
    "diff",
    "discovery_for",
    "domain_clash",
    "held_generation",
    "known_fleets",
    "locate_world",
    "new_generation",
    "plan_record",
    "requests_for",
    "with_planned_agents",
]
