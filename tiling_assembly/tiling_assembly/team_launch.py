"""The launch files' side of the team file: a role's nodes as launch_ros `Node` actions.

Only launch files import this module (it needs `launch` and `launch_ros`); the experiment runner
builds its command lines from the same `team.TeamRole` (tiling_sim.experiment).
"""

from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import get_package_share_directory
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare

from tiling_assembly.team import TeamNode, TeamRole, load_team


def installed_team() -> dict[str, TeamRole]:
    """The team file installed with tiling_assembly (from the repository's config/team.yaml)."""
    return load_team(Path(get_package_share_directory("tiling_assembly")) / "config" / "team.yaml")


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
