"""The node executable this package installs (setup.py). Each catches Ctrl-C and SIGTERM before its node
module and the ROS libraries load: `ros2 launch` may stop a node while it still imports them
(`tiling_assembly.interrupts`)."""

from tiling_assembly.interrupts import run_executable


def planner_node() -> int:
    return run_executable("planner_node.planner_node")
