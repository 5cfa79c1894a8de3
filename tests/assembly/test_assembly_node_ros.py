"""assembly_node as a real ROS 2 process: placements it hears before the structure reaches it
(discovery can deliver the latched structure late) still count when its task starts; its heartbeat
says when its robot's place_tile server is reachable (the experiment starts simulated time then)."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
from conftest import ros2_command, stop_node_process
from rclpy.action import ActionServer
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers.isolated_domains import fresh_domain
from ros_helpers.spinning import spin_until as spin_helper

from tiling_assembly.messages import structure_to_msg
from tiling_assembly.structure_file import load_structure
from tiling_assembly.time_model import TimeModel
from tiling_assembly_msgs.action import PlaceTile
from tiling_assembly_msgs.msg import (
    AssemblyPlan,
    AssemblyTask,
    AuctionAnnouncement,
    AuctionBid,
    AuctioneerStatus,
    PlacementReport,
    RobotStatus,
    Structure,
)

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
    domain = fresh_domain()
    process = subprocess.Popen(command, cwd=REPO, env=domain.environ(), stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    context = domain.context
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
        return spin_helper(executor, predicate, timeout)

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
        executor.shutdown()
        node.destroy_node()
        output = stop_node_process(process)  # also checks it stopped without a traceback
    assert "waits for supports" not in output, output


class RobotUnderTest:
    """assembly_node as /robot1 with a place_tile server that succeeds at once, and the team's topics."""

    def __init__(self) -> None:
        command = [ros2_command(), "run", "assembly_node", "assembly_node", "--ros-args", "-r", "__ns:=/robot1",
                   "--params-file", str(REPO / "config" / "assembly_node.yaml")]
        domain = fresh_domain()
        self.process = subprocess.Popen(command, cwd=REPO, env=domain.environ(), stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True)
        self.context = domain.context
        self.node = Node("assembly_test_team", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.goals: list[int] = []
        self.server = ActionServer(self.node, PlaceTile, "/robot1/place_tile", self.place)
        coordination = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
        self.structure_pub = self.node.create_publisher(Structure, "/structure", LATCHED)
        self.plan_pub = self.node.create_publisher(AssemblyPlan, "/plan", LATCHED)
        self.status_pub = self.node.create_publisher(AuctioneerStatus, "/auction/status", coordination)
        self.announce_pub = self.node.create_publisher(AuctionAnnouncement, "/auction/announcements", coordination)
        self.bids: list[AuctionBid] = []
        self.node.create_subscription(AuctionBid, "/auction/bids", self.bids.append, coordination)

    def place(self, handle):  # type: ignore[no-untyped-def]
        self.goals.append(handle.request.tile_id)
        handle.succeed()
        return PlaceTile.Result(error_code=PlaceTile.Result.SUCCEEDED)

    def spin_until(self, predicate, timeout: float) -> bool:  # type: ignore[no-untyped-def]
        return spin_helper(self.executor, predicate, timeout)

    def plan(self, revision: int, tiles: list[int], structure_name: str, team: int = 1) -> None:
        plan = AssemblyPlan(revision=revision, structure_name=structure_name)
        plan.tasks = [AssemblyTask(robot_name="robot1", tile_ids=tiles)]
        plan.tasks += [AssemblyTask(robot_name=f"robot{k}", tile_ids=[]) for k in range(2, team + 1)]
        self.plan_pub.publish(plan)

    def auctioneer_says(self, seconds: float, plan_revision: int, lost: list[str]) -> None:
        """Publish the auction node's heartbeat for `seconds` while spinning."""
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.status_pub.publish(AuctioneerStatus(plan_revision=plan_revision, lost_robots=lost))
            self.spin_until(lambda: False, 0.1)

    def close(self) -> str:
        self.server.destroy()
        self.executor.shutdown()
        self.node.destroy_node()
        return stop_node_process(self.process)


def test_a_robot_counted_lost_starts_no_tile_until_taken_back_with_the_new_plan() -> None:
    structure = load_structure(REPO / "config" / "structures" / "paper_14.yaml")
    ground = [t for t in structure.tile_ids if not structure.supports[t]]
    robot = RobotUnderTest()
    try:
        assert robot.spin_until(lambda: robot.status_pub.get_subscription_count() > 0, 30.0), "no assembly_node"
        robot.structure_pub.publish(structure_to_msg(structure))
        robot.auctioneer_says(1.0, plan_revision=1, lost=["robot1"])
        robot.plan(1, ground[:1], structure.name)
        robot.auctioneer_says(2.0, plan_revision=2, lost=["robot1"])
        assert robot.goals == [], "a robot the team counts lost started a tile"
        robot.auctioneer_says(1.0, plan_revision=2, lost=[])
        assert robot.goals == [], "started a tile of plan revision 1 while revision 2 is in force"
        robot.plan(2, ground[1:2], structure.name)
        robot.auctioneer_says(3.0, plan_revision=2, lost=[])
        assert robot.goals == ground[1:2]
        robot.auctioneer_says(0.5, plan_revision=2, lost=[])
        robot.spin_until(lambda: False, 2.5)  # the auction node falls silent
        robot.plan(3, ground[2:3], structure.name)
        robot.spin_until(lambda: False, 2.0)
        assert robot.goals == ground[1:2], "a robot that cannot hear the auction node started a tile"
    finally:
        output = robot.close()
    assert "starting no new tile: the auction node counts this robot lost" in output
    assert "starting no new tile: cannot hear the auction node" in output


def test_a_repeated_announcement_gets_the_same_bid_again() -> None:
    structure = load_structure(REPO / "config" / "structures" / "paper_14.yaml")
    robot = RobotUnderTest()
    try:
        assert robot.spin_until(lambda: robot.announce_pub.get_subscription_count() > 0, 30.0), "no assembly_node"
        robot.structure_pub.publish(structure_to_msg(structure))
        robot.plan(0, structure.tile_ids[:3], structure.name)
        robot.spin_until(lambda: False, 1.0)
        announcement = AuctionAnnouncement(auction_id=5, tile_id=structure.tile_ids[-1], bidders=["robot1"])
        robot.announce_pub.publish(announcement)
        assert robot.spin_until(lambda: len(robot.bids) == 1, 5.0), "no bid"
        robot.spin_until(lambda: False, 2.0)  # its task changes meanwhile (it places tiles)
        robot.announce_pub.publish(announcement)
        assert robot.spin_until(lambda: len(robot.bids) == 2, 5.0), "no bid for the repeated announcement"
    finally:
        robot.close()
    assert robot.bids[0].bid == robot.bids[1].bid and robot.bids[1].auction_id == 5


def test_the_workload_in_a_bid_counts_the_plans_robots_crowding_the_caches() -> None:
    """Eight robots on paper_14: every pick costs the larger of (8 / 5 - 1) x 3.5 s at its five caches
    and 7 x 4.5 s x the share of its stops a base blocks beside it (44%), as in the plan
    (TimeModel.for_team); the robot's w_i says so."""
    structure = load_structure(REPO / "config" / "structures" / "paper_14.yaml")
    waiting = 4  # the octagon on 1, 2, 3 and 6, none of them placed: robot1 keeps it in its task
    robot = RobotUnderTest()
    try:
        assert robot.spin_until(lambda: robot.announce_pub.get_subscription_count() > 0, 30.0), "no assembly_node"
        robot.structure_pub.publish(structure_to_msg(structure))
        robot.plan(0, [waiting], structure.name, team=8)
        robot.spin_until(lambda: False, 1.0)
        robot.announce_pub.publish(AuctionAnnouncement(auction_id=1, tile_id=14, bidders=["robot1"]))
        assert robot.spin_until(lambda: len(robot.bids) == 1, 5.0), "no bid"
    finally:
        robot.close()
    crowded = TimeModel().for_team(structure, 8)
    assert crowded.crowding_time == pytest.approx(max(0.6 * 3.5, 7 * 4.5 * TimeModel().stop_share(structure)))
    assert crowded.crowding_time > 10.0
    assert robot.bids[0].workload == pytest.approx(crowded.tile_cost(structure, waiting))
    assert robot.goals == []
