"""The team's shared nodes on real robots: the planner and the auction node (run them once, e.g.
on the VI robot as in the paper, or on a base station).

    ros2 launch auction_node team.launch.py structure_file:=/path/to/structure.yaml \
        robot_names:="[robot1, robot2]"

The nodes are the base station's of config/team.yaml, which the simulation's experiment reads too;
the same parameter files (config/planner_node.yaml, config/auction_node.yaml).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument

from tiling_assembly.team_launch import installed_team, role_nodes


def generate_launch_description() -> LaunchDescription:
    arguments = [
        DeclareLaunchArgument("structure_file", description="the structure to build (YAML)"),
        DeclareLaunchArgument("robot_names", default_value="[robot1, robot2]", description="assembly robots"),
    ]
    return LaunchDescription([*arguments, *role_nodes(installed_team()["base_station"])])
