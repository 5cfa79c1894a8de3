"""vi_explorer as a real ROS 2 process."""

from __future__ import annotations

import subprocess
import time

import pytest
from conftest import stop_node_process
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionServer, GoalResponse
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from ros_helpers.isolated_domains import fresh_domain
from rosgraph_msgs.msg import Clock
from vi_helpers import REPO, STRUCTURES, ros2_command

from tiling_assembly_msgs.action import NavigateTo
from tiling_assembly_msgs.msg import TileStateArray
from tiling_ros.qos import CLOCK, COORDINATION, OTHER_ROBOT_POSES
from tiling_ros.stamps import stamp_from_seconds, stamp_to_nanoseconds

pytestmark = pytest.mark.ros


def start_explorer(domain):  # type: ignore[no-untyped-def]
    """vi_explorer of /vi on paper_14, on simulated time, in `domain`."""
    args = [ros2_command(), "run", "vi_node", "vi_explorer", "--ros-args", "-r", "__ns:=/vi",
            "-p", f"structure_file:={STRUCTURES / 'paper_14.yaml'}", "-p", "use_sim_time:=true"]
    return subprocess.Popen(args, cwd=REPO, env=domain.environ(), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)


def standing_pose() -> PoseStamped:
    """The VI robot's overhead pose where it stands, stamped 0."""
    pose = PoseStamped()
    pose.header.frame_id = "map"
    pose.pose.position.x, pose.pose.orientation.w = 1.5, 1.0
    return pose


def test_the_first_viewpoint_is_chosen_while_the_simulated_clock_still_stands_at_its_start() -> None:
    """A simulator holds its clock at the start until every VI robot has set off: the explorer's
    first goal goes on wall time (on the simulated clock it waited for the clock, which waited for
    it, and a first goal that came when a busy host let it started the VI robot's path late)."""
    domain = fresh_domain()
    node = Node("explorer_probe", context=domain.context)
    executor = SingleThreadedExecutor(context=domain.context)
    executor.add_node(node)
    goals: list[NavigateTo.Goal] = []

    def accept(goal: NavigateTo.Goal) -> GoalResponse:
        goals.append(goal)
        return GoalResponse.REJECT  # where it went is all this test asks

    ActionServer(node, NavigateTo, "/vi/navigate_to", execute_callback=lambda handle: NavigateTo.Result(),
                 goal_callback=accept)
    own_pose = node.create_publisher(PoseStamped, "/vi/overhead_pose", OTHER_ROBOT_POSES)
    process = start_explorer(domain)
    try:
        deadline = time.monotonic() + 60.0
        while not goals and time.monotonic() < deadline:
            own_pose.publish(standing_pose())  # stamped 0: no /clock ever runs here
            executor.spin_once(timeout_sec=0.1)
    finally:
        output = stop_node_process(process)
        executor.shutdown()
        node.destroy_node()
    assert goals, f"no navigate_to goal without a running simulated clock: {output}"
    target = goals[0].target
    assert target.header.stamp.sec == 0 and target.header.stamp.nanosec == 0


def test_a_goal_chosen_on_a_scans_states_is_stamped_with_that_scans_time() -> None:
    """The next viewpoint chosen on the states of the scan taken after an arrival goes out stamped
    with that scan's time, not with the clock's time when the states came (later on a busy host):
    a simulated base sets off at a time that stamp sets, the same on a quiet host and a busy one."""
    domain = fresh_domain()
    node = Node("explorer_probe", context=domain.context)
    executor = SingleThreadedExecutor(context=domain.context)
    executor.add_node(node)
    goals: list[NavigateTo.Goal] = []

    def arrive(handle):  # type: ignore[no-untyped-def]
        goals.append(handle.request)
        handle.succeed()
        result = NavigateTo.Result(success=True)
        result.final_pose.pose = handle.request.target.pose
        result.final_pose.header.stamp = stamp_from_seconds(2.0)  # the base's own arrival time
        return result

    ActionServer(node, NavigateTo, "/vi/navigate_to", execute_callback=arrive)
    own_pose = node.create_publisher(PoseStamped, "/vi/overhead_pose", OTHER_ROBOT_POSES)
    clock = node.create_publisher(Clock, "/clock", CLOCK)
    states = node.create_publisher(TileStateArray, "/tile_states", COORDINATION)
    process = start_explorer(domain)
    try:
        deadline = time.monotonic() + 60.0
        while len(goals) < 2 and time.monotonic() < deadline:
            own_pose.publish(standing_pose())
            if goals:  # arrived at 2.0 s; the clock ran on to 4.0 s while the scan of 2.2 s was judged
                clock.publish(Clock(clock=stamp_from_seconds(4.0)))
                scan = TileStateArray(robot_name="vi", problem="alignment failed: a test's scan")
                scan.header.stamp, scan.header.frame_id = stamp_from_seconds(2.2), "map"
                states.publish(scan)
            executor.spin_once(timeout_sec=0.1)
    finally:
        output = stop_node_process(process)
        executor.shutdown()
        node.destroy_node()
    assert len(goals) == 2, f"no second goal on the states of the scan taken after the arrival: {output}"
    assert stamp_to_nanoseconds(goals[1].target.header.stamp) == 2_200_000_000
    assert "no tile states from this viewpoint" in output
