"""The scanning (VI) robot (paper sections 2.2 and 3.1): its Create base with navigate_to, and,
optionally, a Kinect driver of your choice, remapped onto the topic the inspection expects.

    ros2 launch hardware_drivers vi_robot.launch.py base_port:=/dev/ttyUSB0 \
        start_kinect:=true kinect_package:=<pkg> kinect_executable:=<exe> kinect_points_topic:=<its topic>

Topics this project expects from equipment it does not drive (DESIGN.md's contract):

* the Kinect: sensor_msgs/PointCloud2 on /vi/camera/depth/points, organized (640 x 480 for a
  Kinect v1), fields x y z float32, frame camera_depth_optical_frame, NaN where there is no return.
  The Kinect driver is started in the /vi namespace and its point topic (kinect_points_topic, as
  that driver names it) is remapped to camera/depth/points;
* the overhead cameras: geometry_msgs/PoseStamped (frame map, x, y, yaw of base_link) on
  /vi/overhead_pose, and /robotK/overhead_pose for every assembly robot K. If they publish
  elsewhere, pass overhead_pose_topic:=... and it is remapped for the base navigator.
"""

from launch import LaunchDescription
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from tiling_assembly.team_launch import argument


def generate_launch_description() -> LaunchDescription:
    share = FindPackageShare("hardware_drivers")
    drivers_yaml = PathJoinSubstitution([share, "config", "hardware_drivers.yaml"])
    namespace = LaunchConfiguration("namespace")
    arguments = [
        argument("namespace", "vi", "the scanning robot's namespace"),
        argument("base_port", "/dev/ttyUSB0", "iRobot Create serial port"),
        argument("base_baud", "57600", "57600 (Create 1) or 115200 (Create 2)"),
        argument("overhead_pose_topic", "overhead_pose", "where the overhead cameras publish its pose"),
        argument("start_kinect", "false", "start a Kinect driver node"),
        argument("kinect_package", "kinect_ros2", "package of the Kinect driver"),
        argument("kinect_executable", "kinect_ros2_node", "executable of the Kinect driver"),
        argument("kinect_points_topic", "depth/points", "the driver's name of its point cloud topic"),
    ]
    return LaunchDescription([
        *arguments,
        Node(package="hardware_drivers", executable="create_base", name="create_base", namespace=namespace,
             parameters=[drivers_yaml, {"port": LaunchConfiguration("base_port"),
                                        "baud": LaunchConfiguration("base_baud")}],
             output="screen"),
        Node(package="hardware_drivers", executable="base_navigator", name="base_navigator",
             namespace=namespace, parameters=[drivers_yaml],
             remappings=[("overhead_pose", LaunchConfiguration("overhead_pose_topic"))], output="screen"),
        Node(package=LaunchConfiguration("kinect_package"),
             executable=LaunchConfiguration("kinect_executable"), name="kinect", namespace=namespace,
             condition=IfCondition(LaunchConfiguration("start_kinect")),
             remappings=[(LaunchConfiguration("kinect_points_topic"), "camera/depth/points")],
             output="screen"),
    ])
