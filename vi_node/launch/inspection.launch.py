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
from launch.substitutions import LaunchConfiguration

from tiling_assembly.team_launch import argument, hardware_launch, installed_team, role_nodes


def generate_launch_description() -> LaunchDescription:
    role = installed_team()["vi_robot"]
    namespace = LaunchConfiguration("namespace")
    arguments = [
        # declared here too, so that the base (which declares it as well) and the inspection nodes
        # always share one namespace
        argument("namespace", "vi", "the scanning robot's namespace"),
        argument("base_port", "/dev/ttyUSB0", "Create base port"),
        argument("start_kinect", "false", "start a Kinect driver"),
        argument("structure_file", "", "structure; empty: /structure"),
    ]
    base = hardware_launch(role.hardware, namespace, ["base_port", "start_kinect"])
    return LaunchDescription([*arguments, base, *role_nodes(role, namespace)])
