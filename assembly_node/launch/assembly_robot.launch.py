"""One real assembly robot: its M3 drivers and its assembly_node, in the robot's namespace.

    ros2 launch assembly_node assembly_robot.launch.py namespace:=robot2 \
        base_port:=/dev/ttyUSB0 arm_port:=/dev/ttyUSB1 laser_port:=/dev/ttyACM0

The assembly robot's nodes of config/team.yaml, which the simulation's experiment reads too, with
the same parameters (config/assembly_node.yaml); only the robot behind the place_tile action
differs (hardware_drivers' m3_robot instead of the simulated robot's body).
The team's planner_node and auction_node run once per team (team.launch.py of auction_node).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.substitutions import FindPackageShare

from tiling_assembly.team_launch import installed_team, role_nodes


def generate_launch_description() -> LaunchDescription:
    role = installed_team()["assembly_robot"]
    namespace = LaunchConfiguration("namespace")
    arguments = [
        DeclareLaunchArgument("namespace", default_value="robot1", description="the robot's namespace"),
        DeclareLaunchArgument("base_port", default_value="/dev/ttyUSB0", description="Create base port"),
        DeclareLaunchArgument("arm_port", default_value="/dev/ttyUSB1", description="Dynamixel bus of the arm"),
        DeclareLaunchArgument("laser_port", default_value="/dev/ttyACM0", description="Hokuyo URG port"),
        DeclareLaunchArgument("structure_file", default_value="", description="structure; empty: /structure"),
    ]
    drivers = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare("hardware_drivers"), "launch", role.hardware])
        ),
        launch_arguments={
            "namespace": namespace,
            "base_port": LaunchConfiguration("base_port"),
            "arm_port": LaunchConfiguration("arm_port"),
            "laser_port": LaunchConfiguration("laser_port"),
            "structure_file": LaunchConfiguration("structure_file"),
        }.items(),
    )
    return LaunchDescription([*arguments, drivers, *role_nodes(role, namespace)])
