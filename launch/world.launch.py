"""Start the shared PyBullet world of a fleet with `ros2 launch` (hand-written, not generated).

    fleet ament-prefix          # once: prints the prefix to add to AMENT_PREFIX_PATH
    ros2 launch launch/world.launch.py config:=/path/to/world.yaml [status_file:=/path/world.status.json] \
        [as_fast_as_possible:=false] [log_level:=info]

`config` is a world.yaml (schema in docs/architecture.md, section World); the world re-reads it
when it changes, so robots join and leave without a restart.
"""

from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from launch import LaunchDescription


def _world_node(context):
    arguments = ["--config", LaunchConfiguration("config").perform(context)]
    status_file = LaunchConfiguration("status_file").perform(context)
    if status_file:
        arguments += ["--status-file", status_file]
    if LaunchConfiguration("as_fast_as_possible").perform(context).strip().lower() in ("true", "1"):
        arguments.append("--as-fast-as-possible")
    return [
        Node(
            package="fleet_nodes",
            executable="world",
            name="world",
            output="screen",
            arguments=arguments,
            ros_arguments=["--log-level", LaunchConfiguration("log_level").perform(context)],
            respawn=True,
            respawn_delay=1.0,
        )
    ]


def generate_launch_description():
    return LaunchDescription(
        [
            DeclareLaunchArgument("config", description="world.yaml describing obstacles and robots"),
            DeclareLaunchArgument(
                "status_file",
                default_value="",
                description="JSON status written a few times a second; robots restart from it",
            ),
            DeclareLaunchArgument(
                "as_fast_as_possible", default_value="false", description="true: do not pace to the wall clock"
            ),
            DeclareLaunchArgument("log_level", default_value="info"),
            OpaqueFunction(function=_world_node),
        ]
    )
