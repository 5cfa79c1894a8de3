"""auction_node as a real ROS 2 process, when only scans decide (robots_find_missing false): a
support a robot found absent waits for a scan to confirm it, and is acted on after
unconfirmed_report_timeout if none does, so the robot that found it does not wait forever. A tile
called missing and then found lying wrong is repaired once, by one robot. Copies of an
announcement go out until every robot has bid; under simulated time an auction closes when the
clock passes its deadline, however much wall time goes by."""

from __future__ import annotations

import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import ros2_command, stop_node_process
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers.isolated_domains import fresh_domain
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from tiling_assembly.messages import structure_to_msg
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import (
    AuctionAnnouncement,
    AuctionAward,
    AuctionBid,
    PlacementReport,
    RobotStatus,
    Structure,
    TileState,
    TileStateArray,
)
from tiling_ros import team_topics as topics
from tiling_ros.stamps import stamp_from_seconds, stamp_to_seconds

pytestmark = pytest.mark.ros

REPO = Path(__file__).resolve().parents[2]
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
REPORTS = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
RELIABLE = QoSProfile(depth=50, reliability=ReliabilityPolicy.RELIABLE)
DECISIONS = QoSProfile(depth=200, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
TIMEOUT = 3.0  # s, unconfirmed_report_timeout of the node under test


class Team:
    """Stands in for the structure publisher, two assembly robots and the inspection."""

    def __init__(self) -> None:
        self.domain = fresh_domain()
        self.context = self.domain.context
        self.node = Node("auction_test_team", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.announcements: list[tuple[float, AuctionAnnouncement]] = []
        self.decisions: list[str] = []
        self.awards: list[AuctionAward] = []
        topics.AWARDS.subscribe(self.node, self.awards.append)
        self.bid_pub = topics.BIDS.publisher(self.node)
        self.node.create_subscription(AuctionAnnouncement, "/auction/announcements",
                                      lambda m: self.announcements.append((time.monotonic(), m)), RELIABLE)
        self.node.create_subscription(String, "/auction/decisions", lambda m: self.decisions.append(m.data),
                                      DECISIONS)
        self.structure_pub = self.node.create_publisher(Structure, "/structure", LATCHED)
        self.report_pub = self.node.create_publisher(PlacementReport, "/placement_reports", REPORTS)
        self.states_pub = self.node.create_publisher(TileStateArray, "/tile_states", RELIABLE)
        self.status_pub = self.node.create_publisher(RobotStatus, "/robot_status", RELIABLE)
        self.node.create_timer(0.2, self.heartbeats)

    def heartbeats(self) -> None:
        for robot in ("robot1", "robot2"):
            self.status_pub.publish(RobotStatus(robot_name=robot))

    def spin_until(self, predicate: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)
            if predicate():
                return
        raise AssertionError(f"no {what} within {timeout} s; decisions so far: {self.decisions}")

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def report(self, tile_id: int, outcome: int, missing: tuple[int, ...] = (), robot: str = "robot1",
               wrong: tuple[int, ...] = ()) -> None:
        msg = PlacementReport(robot_name=robot, tile_id=tile_id, outcome=outcome, attempts=1,
                              missing_supports=list(missing), wrong_tiles=list(wrong))
        msg.header.stamp = self.node.get_clock().now().to_msg()
        self.report_pub.publish(msg)

    def scan(self, missing: int, camera_x: float) -> None:
        msg = TileStateArray()
        msg.header.stamp = self.node.get_clock().now().to_msg()
        msg.camera_pose.position.x = camera_x
        msg.states = [TileState(tile_id=missing, state=TileState.MISSING, scan_count=1, see_through_support=200)]
        self.states_pub.publish(msg)

    def bid(self, auction_id: int, robot: str, value: float) -> None:
        self.bid_pub.publish(AuctionBid(auction_id=auction_id, robot_name=robot, bid=value))

    def announced(self, tile_id: int) -> list[tuple[float, AuctionAnnouncement]]:
        """The auctions opened for `tile_id` (an announcement is repeated until every robot bids)."""
        first: dict[int, tuple[float, AuctionAnnouncement]] = {}
        for t, a in self.announcements:
            if a.tile_id == tile_id:
                first.setdefault(a.auction_id, (t, a))
        return list(first.values())

    def copies(self, auction_id: int) -> int:
        return sum(1 for _, a in self.announcements if a.auction_id == auction_id)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


def auction_node_with(*parameters: str) -> Iterator[tuple[Team, Any]]:
    """auction_node started with `parameters` (besides the test's usual ones), and a team."""
    structure = load_structure(REPO / "config" / "structures" / "paper_14.yaml")
    command = [ros2_command(), "run", "auction_node", "auction_node", "--ros-args",
               "--params-file", str(REPO / "config" / "auction_node.yaml"),
               "-p", "robots_find_missing:=false", "-p", f"unconfirmed_report_timeout:={TIMEOUT}",
               "-p", "confirmations:=1", "-p", "confirmation_view_change:=0.0"]
    for parameter in parameters:
        command += ["-p", parameter]
    team = Team()
    process = subprocess.Popen(command, cwd=REPO, env=team.domain.environ(), stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    try:
        team.structure_pub.publish(structure_to_msg(structure))
        team.spin_until(lambda: team.report_pub.get_subscription_count() > 0
                        and team.states_pub.get_subscription_count() > 0, 30.0, "auction node")
        team.spin_for(1.0)  # the auction node hears robot1's heartbeat
        yield team, structure
    finally:
        team.close()
        stop_node_process(process)  # checks it stopped cleanly, without a traceback


@pytest.fixture
def team() -> Iterator[tuple[Team, Any]]:
    yield from auction_node_with()


@pytest.fixture
def team_on_simulated_time() -> Iterator[tuple[Team, Any]]:
    yield from auction_node_with("use_sim_time:=true")


def test_a_report_no_scan_confirms_is_acted_on_after_the_timeout(team: tuple[Team, Any]) -> None:
    team, structure = team
    tile = next(t for t in structure.tile_ids if structure.supports[t])
    support = structure.supports[tile][0]
    team.report(support, PlacementReport.OUTCOME_PLACED)
    team.spin_for(0.3)
    reported = time.monotonic()
    team.report(tile, PlacementReport.OUTCOME_SUPPORT_MISSING, (support,))
    team.spin_until(lambda: any("waiting up to" in d for d in team.decisions), 5.0, "decision to wait")
    team.spin_for(TIMEOUT - 1.0)
    assert team.announced(support) == [], "acted on the robot's report before the timeout"
    team.spin_until(lambda: team.announced(support), 5.0, "announcement after the timeout")
    (at, announcement), = team.announced(support)
    assert announcement.reason == AuctionAnnouncement.REASON_FOUND_MISSING
    assert at - reported >= TIMEOUT - 0.2
    # decisions and announcements are different topics: either may arrive first
    team.spin_until(lambda: any(f"no scan confirmed it within {TIMEOUT:g} s" in d for d in team.decisions), 2.0,
                    "the decision line")


def test_a_scan_that_confirms_the_report_is_acted_on_once(team: tuple[Team, Any]) -> None:
    team, structure = team
    tile = next(t for t in structure.tile_ids if structure.supports[t])
    support = structure.supports[tile][0]
    team.report(support, PlacementReport.OUTCOME_PLACED)
    team.spin_for(0.3)
    team.report(tile, PlacementReport.OUTCOME_SUPPORT_MISSING, (support,))
    team.spin_for(0.5)
    team.scan(support, camera_x=1.0)
    team.spin_until(lambda: team.announced(support), 5.0, "announcement of the scan's finding")
    team.spin_for(TIMEOUT + 1.0)
    (_, announcement), = team.announced(support)
    assert announcement.reason == AuctionAnnouncement.REASON_MISSING
    # robot1 never bids: its invitation went out again every resend_period until the deadline
    assert 20 <= team.copies(announcement.auction_id) <= 50  # 2 s window, resend_period 0.05 s


def called_missing(team: Team, structure: Any) -> AuctionAnnouncement:
    """A placed tile a scan calls missing: its re-placement's announcement."""
    tile = next(t for t in structure.tile_ids if structure.supports[t])
    team.report(tile, PlacementReport.OUTCOME_PLACED)
    team.spin_for(0.3)
    team.scan(tile, camera_x=1.0)
    team.spin_until(lambda: team.announced(tile), 5.0, "re-placement auction")
    return team.announced(tile)[0][1]


def called_missing_then_found_in_the_way(team: Team, structure: Any) -> tuple[int, AuctionAnnouncement]:
    """A placed tile a scan calls missing (its re-placement auctioned), then robot1 finds it lying
    wrong in the way of another tile; returns the tile and its re-placement announcement."""
    replacement = called_missing(team, structure)
    assert replacement.reason == AuctionAnnouncement.REASON_MISSING
    return replacement.tile_id, replacement


def found_in_the_way(team: Team, structure: Any, tile: int) -> None:
    blocked = next(t for t in structure.tile_ids if t != tile)
    team.report(blocked, PlacementReport.OUTCOME_BLOCKED, robot="robot1", wrong=(tile,))


def test_a_tile_found_lying_wrong_while_its_replacement_is_auctioned_is_repaired_instead(
        team: tuple[Team, Any]) -> None:
    team, structure = team
    tile, replacement = called_missing_then_found_in_the_way(team, structure)
    found_in_the_way(team, structure, tile)
    team.spin_until(lambda: len(team.announced(tile)) == 2, 5.0, "repair auction")
    repair = team.announced(tile)[1][1]
    assert repair.reason == AuctionAnnouncement.REASON_MISPLACED
    assert repair.bidders == ["robot1", "robot2"]
    team.bid(repair.auction_id, "robot1", 3.0)
    team.bid(repair.auction_id, "robot2", 4.0)
    team.spin_until(lambda: any(a.auction_id == repair.auction_id for a in team.awards), 5.0, "repair award")
    team.spin_for(3.0)  # past the withdrawn auction's deadline
    assert {a.auction_id for a in team.awards} == {repair.auction_id}, "the withdrawn auction was awarded too"
    assert any(f"auction {replacement.auction_id} to place it again is withdrawn" in d for d in team.decisions)


def test_a_tile_found_lying_wrong_after_its_replacement_was_won_is_repaired_by_the_winner(
        team: tuple[Team, Any]) -> None:
    team, structure = team
    tile, replacement = called_missing_then_found_in_the_way(team, structure)
    team.bid(replacement.auction_id, "robot1", 9.0)
    team.bid(replacement.auction_id, "robot2", 5.0)
    team.spin_until(lambda: any(a.winner == "robot2" for a in team.awards), 5.0, "re-placement award to robot2")
    found_in_the_way(team, structure, tile)
    team.spin_until(lambda: len(team.announced(tile)) == 2, 5.0, "repair auction")
    repair = team.announced(tile)[1][1]
    assert repair.reason == AuctionAnnouncement.REASON_MISPLACED
    assert repair.bidders == ["robot2"], "another robot could win the repair while robot2 carries the tile there"
    team.spin_until(lambda: any("robot2, which is to place it again, does it" in d for d in team.decisions), 2.0,
                    "the decision line")



def test_copies_of_an_announcement_stop_once_every_robot_has_bid(team: tuple[Team, Any]) -> None:
    team, structure = team
    auction = called_missing(team, structure).auction_id
    team.spin_for(0.3)
    assert team.copies(auction) >= 3, "robots that have not bid are not invited again"
    team.bid(auction, "robot1", 2.0)
    team.bid(auction, "robot2", 1.0)
    team.spin_until(lambda: any(a.auction_id == auction for a in team.awards), 2.0, "award")
    team.spin_for(0.2)
    copies = team.copies(auction)
    team.spin_for(1.0)
    assert team.copies(auction) == copies, "copies went on after every robot had bid"


def test_under_simulated_time_an_auction_closes_when_the_clock_passes_its_deadline_whatever_the_wall_time(
        team_on_simulated_time: tuple[Team, Any]) -> None:
    """robot2 never bids: the auction closes at its deadline (bid_window 2 s of node time). While the
    simulated clock stands still no wall time closes it; once the clock passes it, it closes."""
    team, structure = team_on_simulated_time
    clock = team.node.create_publisher(Clock, "/clock", 10)
    now = [100.0]
    team.node.create_timer(0.05, lambda: clock.publish(Clock(clock=stamp_from_seconds(now[0]))))
    team.spin_for(0.5)
    auction = called_missing(team, structure)
    assert abs(stamp_to_seconds(auction.deadline) - 102.0) < 0.2, "the deadline is not in simulated time"
    team.bid(auction.auction_id, "robot1", 2.0)
    team.spin_for(3.0)  # more wall time than the bid window
    assert team.awards == [], "the auction closed on wall time while the simulated clock stood still"
    now[0] = 102.5
    team.spin_until(lambda: team.awards, 2.0, "award once the clock passed the deadline")
    assert team.awards[0].winner == "robot1"
