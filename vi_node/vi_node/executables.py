"""The node executables this package installs (setup.py). Each catches Ctrl-C and SIGTERM before its node
module and the ROS libraries load: `ros2 launch` may stop a node while it still imports them
(`tiling_assembly.interrupts`)."""

from tiling_assembly.interrupts import run_command, run_executable


def vi_node() -> int:
    return run_executable("vi_node.node")


def vi_explorer() -> int:
    return run_executable("vi_node.explorer_node")


def classify() -> int:
    return run_command("vi_node.classify_bag")
