"""The node executables this package installs (setup.py). Each catches Ctrl-C and SIGTERM before its node
module and the ROS libraries load: `ros2 launch` may stop a node while it still imports them
(`tiling_assembly.interrupts`)."""

from tiling_assembly.interrupts import run_executable


def create_base() -> int:
    return run_executable("hardware_drivers.create_base_node")


def crustcrawler_arm() -> int:
    return run_executable("hardware_drivers.crustcrawler_arm_node")


def hokuyo_urg() -> int:
    return run_executable("hardware_drivers.hokuyo_urg_node")


def m3_robot() -> int:
    return run_executable("hardware_drivers.m3_robot_node")


def base_navigator() -> int:
    return run_executable("hardware_drivers.base_navigator_node")


def create_emulator() -> int:
    return run_executable("hardware_drivers.emulators.create_emulator")


def dynamixel_emulator() -> int:
    return run_executable("hardware_drivers.emulators.dynamixel_emulator")


def urg_emulator() -> int:
    return run_executable("hardware_drivers.emulators.urg_emulator")
