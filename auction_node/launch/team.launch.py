"""The team's shared nodes on real robots: the planner and the auction node (run them once, e.g.
on the VI robot as in the paper, or on a base station).

    ros2 launch auction_node team.launch.py structure_file:=/path/to/structure.yaml \
        robot_names:="[robot1, robot2]"

Same nodes and parameters as in the simulation (config/planner_node.yaml, config/auction_node.yaml).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue
from launch_ros.substitutions import FindPackageShare


def generate_launch_description() -> LaunchDescription:
    arguments = [
        DeclareLaunchArgument("structure_file", description="the structure to build (YAML)"),
        DeclareLaunchArgument("robot_names", default_value="[robot1, robot2]", description="assembly robots"),
    ]
    planner = Node(
        package="planner_node",
        executable="planner_node",
        name="planner_node",
        parameters=[
            PathJoinSubstitution([FindPackageShare("planner_node"), "config", "planner_node.yaml"]),
            {
                "structure_file": LaunchConfiguration("structure_file"),
                # a typed list: launch parses "[robot1, robot2]" as YAML and checks every item is a
                # string; a bare `list` is not a type launch knows ("Unrecognized data type")
                "robot_names": ParameterValue(LaunchConfiguration("robot_names"), value_type=list[str]),
            },
        ],
        output="screen",
    )
    auction = Node(
        package="auction_node",
        executable="auction_node",
        name="auction_node",
        parameters=[PathJoinSubstitution([FindPackageShare("auction_node"), "config", "auction_node.yaml"])],
        output="screen",
    )
    return LaunchDescription([*arguments, planner, auction])
