"""Expansion: a validated FleetSpec -> per-robot launch bundles and the world bundle (pure)."""

from fleet.expand.bundle import Bundle
from fleet.expand.expansion import Expansion, RobotPlan, expand_fleet

__all__ = ["Bundle", "Expansion", "RobotPlan", "expand_fleet"]
