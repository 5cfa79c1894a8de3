"""One real assembly robot: its M3 drivers and its assembly_node, in the robot's namespace.

    ros2 launch assembly_node assembly_robot.launch.py namespace:=robot2 \
        base_port:=/dev/ttyUSB0 arm_port:=/dev/ttyUSB1 laser_port:=/dev/ttyACM0

The assembly robot's nodes of config/team.yaml, which the simulation's experiment reads too, with
the same parameters (config/assembly_node.yaml); only the robot behind the place_tile action
differs (hardware_drivers' m3_robot instead of the simulated robot's body).
The team's planner_node and auction_node run once per team (team.launch.py of auction_node).
"""

from launch import LaunchDescription
from launch.substitutions import LaunchConfiguration

from tiling_assembly.team_launch import argument, hardware_launch, installed_team, role_nodes


def generate_launch_description() -> LaunchDescription:
    role = installed_team()["assembly_robot"]
    namespace = LaunchConfiguration("namespace")
    arguments = [
        argument("namespace", "robot1", "the robot's namespace"),
        argument("base_port", "/dev/ttyUSB0", "Create base port"),
        argument("arm_port", "/dev/ttyUSB1", "Dynamixel bus of the arm"),
        argument("laser_port", "/dev/ttyACM0", "Hokuyo URG port"),
        argument("structure_file", "", "structure; empty: /structure"),
    ]
    drivers = hardware_launch(role.hardware, namespace, ["base_port", "arm_port", "laser_port", "structure_file"])
    return LaunchDescription([*arguments, drivers, *role_nodes(role, namespace)])
