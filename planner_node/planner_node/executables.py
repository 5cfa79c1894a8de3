"""The executables this package installs (setup.py). Each catches Ctrl-C and SIGTERM before its node
module and the ROS libraries load: `ros2 launch` may stop a node while it still imports them
(`tiling_assembly.interrupts`)."""

from tiling_assembly.interrupts import run_command, run_executable


def planner_node() -> int:
    return run_executable("planner_node.planner_node")


def plan() -> int:
    return run_command("planner_node.plan_command")


def benchmark() -> int:
    return run_command("planner_node.benchmark")
