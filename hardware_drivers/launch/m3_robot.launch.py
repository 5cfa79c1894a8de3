"""One real M3 assembly robot (paper section 3.1): Create base, CrustCrawler arm, Hokuyo URG and the
place_tile action server, all in the robot's namespace.

    ros2 launch hardware_drivers m3_robot.launch.py namespace:=robot1 \
        base_port:=/dev/ttyUSB0 arm_port:=/dev/ttyUSB1 laser_port:=/dev/ttyACM0

The overhead cameras are not driven here: they must publish the base's pose as
geometry_msgs/PoseStamped (frame map) on /<namespace>/overhead_pose; if yours publish elsewhere,
pass overhead_pose_topic:=/where/they/publish and it is remapped.
"""

from launch import LaunchDescription
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import Node
from launch_ros.substitutions import FindPackageShare

from tiling_assembly.team_launch import argument


def generate_launch_description() -> LaunchDescription:
    config = PathJoinSubstitution([FindPackageShare("hardware_drivers"), "config"])
    drivers_yaml = PathJoinSubstitution([config, "hardware_drivers.yaml"])
    arm_yaml = PathJoinSubstitution([config, "crustcrawler_arm.yaml"])
    namespace = LaunchConfiguration("namespace")
    arguments = [
        argument("namespace", "robot1", "the robot's namespace"),
        argument("base_port", "/dev/ttyUSB0", "iRobot Create serial port"),
        argument("base_baud", "57600", "57600 (Create 1) or 115200 (Create 2)"),
        argument("arm_port", "/dev/ttyUSB1", "Dynamixel bus of the arm"),
        argument("laser_port", "/dev/ttyACM0", "Hokuyo URG port"),
        argument("structure_file", "", "structure file for tile footprints; empty: use /structure"),
        argument("overhead_pose_topic", "overhead_pose", "where the overhead cameras publish its pose"),
    ]
    overhead = [("overhead_pose", LaunchConfiguration("overhead_pose_topic"))]
    return LaunchDescription([
        *arguments,
        Node(package="hardware_drivers", executable="create_base", name="create_base", namespace=namespace,
             parameters=[drivers_yaml, {"port": LaunchConfiguration("base_port"),
                                        "baud": LaunchConfiguration("base_baud")}],
             output="screen"),
        Node(package="hardware_drivers", executable="crustcrawler_arm", name="crustcrawler_arm",
             namespace=namespace,
             parameters=[drivers_yaml, arm_yaml, {"port": LaunchConfiguration("arm_port")}],
             output="screen"),
        Node(package="hardware_drivers", executable="hokuyo_urg", name="hokuyo_urg", namespace=namespace,
             parameters=[drivers_yaml, {"port": LaunchConfiguration("laser_port")}], output="screen"),
        Node(package="hardware_drivers", executable="m3_robot", name="m3_robot", namespace=namespace,
             parameters=[drivers_yaml, arm_yaml, {"structure_file": LaunchConfiguration("structure_file")}],
             remappings=overhead, output="screen"),
    ])
