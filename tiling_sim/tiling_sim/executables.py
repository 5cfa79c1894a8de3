"""The executables this package installs (setup.py). Each catches Ctrl-C and SIGTERM before its
module and the ROS libraries load: `ros2 launch` may stop a node while it still imports them
(`tiling_assembly.interrupts`)."""

from tiling_assembly.interrupts import run_command, run_executable


def experiment() -> int:
    """Not a node: the runner of the team; an interruption exits 130, as it does once running."""
    return run_executable("tiling_sim.experiment", interrupted_exit_code=130)


def sim_world() -> int:
    return run_executable("tiling_sim.world_node")


def sim_robot() -> int:
    return run_executable("tiling_sim.robot_body_node")


def sim_vi() -> int:
    return run_executable("tiling_sim.vi_body_node")


def replay_bag() -> int:
    return run_command("tiling_sim.replay_bag")


def vi_accuracy() -> int:
    return run_command("tiling_sim.vi_accuracy")


def vi_benchmark() -> int:
    return run_command("tiling_sim.vi_benchmark")


def classify_benchmark() -> int:
    return run_command("tiling_sim.classify_benchmark")
