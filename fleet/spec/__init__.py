"""The fleet spec: loading a YAML file with source positions, and validating it."""

from fleet.spec.load import load_spec, parse_spec
from fleet.spec.model import FleetSpec

__all__ = ["FleetSpec", "load_spec", "parse_spec"]
