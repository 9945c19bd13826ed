"""The ROS package `fleet_nodes`: controller, battery and safety nodes, and the composite process.

NODES maps executable names to "module:Class" so that importing this package (as the CLI and the
runtime do) never loads rclpy; load_node_class() imports on demand.
"""

from __future__ import annotations

import importlib

NODES: dict[str, str] = {
    "controller": "fleet.nodes.controller:ControllerNode",
    "battery": "fleet.nodes.battery:BatteryNode",
    "safety": "fleet.nodes.safety:SafetyNode",
}


def load_node_class(executable: str) -> type:
    """The Node subclass behind an executable name; KeyError names the known ones."""
    try:
        target = NODES[executable]
    except KeyError:
        known = ", ".join(sorted(NODES))
        raise KeyError(f"unknown fleet node '{executable}' (known: {known})") from None
    module_name, class_name = target.split(":")
    return getattr(importlib.import_module(module_name), class_name)
