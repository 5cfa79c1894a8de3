"""The launch files' side of the team file: a role's nodes as launch_ros `Node` actions, and the
parts the robot launch files share (a declared argument, a role's hardware launch file included).

Only launch files import this module (it needs `launch` and `launch_ros`); the experiment runner
builds its command lines from the same `team.TeamRole` (tiling_sim.experiment).
"""

from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

from tiling_assembly.team import TeamNode, TeamRole, load_team


def installed_team() -> dict[str, TeamRole]:
    """The team file installed with tiling_assembly (from the repository's config/team.yaml)."""
    return load_team(Path(get_package_share_directory("tiling_assembly")) / "config" / "team.yaml")


def argument(name: str, default: str, description: str) -> DeclareLaunchArgument:
    """A launch argument with its default value and description."""
    return DeclareLaunchArgument(name, default_value=default, description=description)


def hardware_launch(file_name: str, namespace: LaunchConfiguration, forwarded: list[str]) -> IncludeLaunchDescription:
    """hardware_drivers' launch file `file_name` (a role's `hardware`) in `namespace`, given the launch
    arguments named in `forwarded` as this launch file has them."""
    return IncludeLaunchDescription(
        PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare("hardware_drivers"), "launch", file_name])
        ),
        launch_arguments={"namespace": namespace, **{name: LaunchConfiguration(name) for name in forwarded}}.items(),
    )


def role_nodes(role: TeamRole, namespace: LaunchConfiguration | str = "") -> list[Node]:
    """The `Node` actions of `role`, in `namespace` (default: the role's own), with their parameter
    files from the share/ folder of their package and the launch arguments they need."""
    where = namespace or role.namespace_of().lstrip("/")
    return [_node(node, where) for node in role.nodes]


def _node(node: TeamNode, namespace: LaunchConfiguration | str) -> Node:
    files = [PathJoinSubstitution([FindPackageShare(node.package), "config", name]) for name in node.parameters]
    arguments: dict[str, object] = {}
    for need in node.needs:
        value = LaunchConfiguration(need)
        arguments[need] = ParameterValue(value, value_type=list[str]) if need == "robot_names" else value
    return Node(
        package=node.package,
        executable=node.executable,
        name=node.executable,
        namespace=namespace,
        parameters=[*files, arguments] if arguments else files,
        output="screen",
    )
