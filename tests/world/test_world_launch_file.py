"""launch/world.launch.py: launch/launch_ros are not installable here, so check the file against
stand-in modules recording what it builds."""

import sys
import types
from pathlib import Path

LAUNCH_FILE = Path(__file__).resolve().parents[2] / "launch" / "world.launch.py"


class _Recorder:
    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs


class _Config:
    def __init__(self, name):
        self.name = name

    def perform(self, context):
        return context[self.name]


def _module(name: str, **attributes: object) -> types.ModuleType:
    module = types.ModuleType(name)
    module.__dict__.update(attributes)
    return module


def test_world_launch_file_builds_the_world_node(monkeypatch):
    launch = _module("launch", LaunchDescription=_Recorder)
    actions = _module("launch.actions", DeclareLaunchArgument=_Recorder, OpaqueFunction=_Recorder)
    substitutions = _module("launch.substitutions", LaunchConfiguration=_Config)
    launch_ros = _module("launch_ros")
    ros_actions = _module("launch_ros.actions", Node=_Recorder)
    for name, module in {
        "launch": launch,
        "launch.actions": actions,
        "launch.substitutions": substitutions,
        "launch_ros": launch_ros,
        "launch_ros.actions": ros_actions,
    }.items():
        monkeypatch.setitem(sys.modules, name, module)
    namespace: dict = {}
    exec(compile(LAUNCH_FILE.read_text(), str(LAUNCH_FILE), "exec"), namespace)
    description = namespace["generate_launch_description"]()
    declared = [a.args[0] for a in description.args[0] if a.args and isinstance(a.args[0], str)]
    assert declared == ["config", "status_file", "as_fast_as_possible", "log_level"]
    opaque = description.args[0][-1]
    context = {
        "config": "/w/world.yaml",
        "status_file": "/w/s.json",
        "as_fast_as_possible": "True",
        "log_level": "info",
    }
    (node,) = opaque.kwargs["function"](context)
    assert node.kwargs["package"] == "fleet_nodes" and node.kwargs["executable"] == "world"
    assert node.kwargs["arguments"] == [
        "--config",
        "/w/world.yaml",
        "--status-file",
        "/w/s.json",
        "--as-fast-as-possible",
    ]
