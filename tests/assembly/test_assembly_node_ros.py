"""assembly_node as a real ROS 2 process: placements it hears before the structure reaches it
(discovery can deliver the latched structure late) still count when its task starts; its heartbeat
says when its robot's place_tile server is reachable (the experiment starts simulated time then)."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
import rclpy
from conftest import ros2_command, stop_node_process
from rclpy.action import ActionServer
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from tiling_assembly.messages import structure_to_msg
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import PlaceTile
from tiling_assembly_msgs.msg import AssemblyPlan, AssemblyTask, PlacementReport, RobotStatus, Structure

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
REPORTS = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


def test_placements_heard_before_the_structure_count() -> None:
    structure = load_structure(REPO / "config" / "structures" / "paper_14.yaml")
    tile = 4  # an octagon on tiles 1, 2, 3 and 6, all placed by another robot
    supports = structure.supports[tile]
    command = [ros2_command(), "run", "assembly_node", "assembly_node", "--ros-args", "-r", "__ns:=/robot1",
               "--params-file", str(REPO / "config" / "assembly_node.yaml")]
    process = subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    context = Context()
    rclpy.init(context=context)
    node = Node("assembly_test_team", context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    goals: list[int] = []

    def place(handle):  # type: ignore[no-untyped-def]
        goals.append(handle.request.tile_id)
        handle.succeed()
        return PlaceTile.Result(error_code=PlaceTile.Result.SUCCEEDED)

    server = ActionServer(node, PlaceTile, "/robot1/place_tile", place)
    reports = node.create_publisher(PlacementReport, "/placement_reports", REPORTS)
    structure_pub = node.create_publisher(Structure, "/structure", LATCHED)
    plan_pub = node.create_publisher(AssemblyPlan, "/plan", LATCHED)
    statuses: list[RobotStatus] = []
    node.create_subscription(RobotStatus, "/robot_status", statuses.append, 10)

    def spin_until(predicate, timeout: float) -> bool:  # type: ignore[no-untyped-def]
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            if predicate():
                return True
        return False

    try:
        assert spin_until(lambda: reports.get_subscription_count() > 0, 30.0), "assembly_node did not come up"
        assert spin_until(lambda: any(s.driver_ready for s in statuses), 20.0), "no heartbeat with the driver ready"
        for support in supports:
            msg = PlacementReport(robot_name="robot2", tile_id=support, outcome=PlacementReport.OUTCOME_PLACED)
            msg.header.stamp = node.get_clock().now().to_msg()
            reports.publish(msg)
        spin_until(lambda: False, 1.0)  # delivered live, while the robot has no structure yet
        structure_pub.publish(structure_to_msg(structure))
        plan = AssemblyPlan(revision=0, structure_name=structure.name)
        plan.tasks = [AssemblyTask(robot_name="robot1", tile_ids=[tile])]
        plan_pub.publish(plan)
        assert spin_until(lambda: tile in goals, 20.0), f"robot1 never placed tile {tile} (goals: {goals})"
    finally:
        server.destroy()
        node.destroy_node()
        rclpy.shutdown(context=context)
        output = stop_node_process(process)  # also checks it stopped without a traceback
    assert "waits for supports" not in output, output
