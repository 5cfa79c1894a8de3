"""The scanning (VI) robot on real hardware: its base drivers, vi_node and vi_explorer in /vi.

    ros2 launch vi_node inspection.launch.py base_port:=/dev/ttyUSB0 start_kinect:=true \
        structure_file:=/path/to/structure.yaml

The arguments of vi_robot.launch.py (kinect_package, kinect_executable, kinect_points_topic,
base_baud, overhead_pose_topic) can be given here too; namespace moves the whole robot.

The base, its navigate_to server and (optionally) the Kinect driver come from hardware_drivers'
vi_robot.launch.py, which remaps the driver's organized cloud onto /vi/camera/depth/points
(frame camera_depth_optical_frame); the overhead cameras must publish geometry_msgs/PoseStamped
(frame map) on /vi/overhead_pose. The nodes are the VI robot's of config/team.yaml, which the
simulation's experiment reads too, with the same parameters (config/vi_node.yaml).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.substitutions import FindPackageShare

from tiling_assembly.team_launch import installed_team, role_nodes


def generate_launch_description() -> LaunchDescription:
    role = installed_team()["vi_robot"]
    namespace = LaunchConfiguration("namespace")
    arguments = [
        # declared here too, so that the base (which declares it as well) and the inspection nodes
        # always share one namespace
        DeclareLaunchArgument("namespace", default_value="vi", description="the scanning robot's namespace"),
        DeclareLaunchArgument("base_port", default_value="/dev/ttyUSB0", description="Create base port"),
        DeclareLaunchArgument("start_kinect", default_value="false", description="start a Kinect driver"),
        DeclareLaunchArgument("structure_file", default_value="", description="structure; empty: /structure"),
    ]
    base = IncludeLaunchDescription(
        PythonLaunchDescriptionSource(
            PathJoinSubstitution([FindPackageShare("hardware_drivers"), "launch", role.hardware])
        ),
        launch_arguments={
            "namespace": namespace,
            "base_port": LaunchConfiguration("base_port"),
            "start_kinect": LaunchConfiguration("start_kinect"),
        }.items(),
    )
    return LaunchDescription([*arguments, base, *role_nodes(role, namespace)])
