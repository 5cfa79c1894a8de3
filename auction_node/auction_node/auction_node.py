"""auction_node: finds missing tiles and auctions them to the team (paper section 2.3).

A thin adapter around `mismatch.MismatchDetector`, `auction.AuctionBook` and `liveness.Liveness`.
In: `/placement_reports` (q), `/tile_states` (q^s), `/auction/bids`, `/auction/acceptances`,
`/robot_status` heartbeats. Out: `/auction/announcements`, `/auction/awards` and one readable line
per decision on `/auction/decisions` (std_msgs/String) and in the log.

Beyond the paper: a robot whose heartbeat stops is left out of auctions and its unplaced tiles go
to the others through the planner's `/replan` service (a fresh partition and order of everything
not yet placed, for the robots still alive), which keeps the team's work balanced and its orders
consistent with precedence; if the planner does not answer, its tiles are auctioned one by one
instead; a lost robot heard again is given a share by another replan. A tile a robot gave up on
is auctioned among the others, and a support a robot found physically absent when placing on it is
missing just as if a scan had said so. Over a lossy link, announcements and awards are repeated
until answered (`delivery`), and `/auction/status` tells robots the plan in force and who is
counted lost (`assembly_node.team_contact`).

Beyond the paper too (its future work): a placed tile confirmed lying wrong (MISPLACED from two
camera positions, `mismatch.MismatchDetector.flagged`, or a robot that found it in the way,
OUTCOME_BLOCKED) is auctioned as a repair (REASON_MISPLACED) with the placed tiles resting on it,
which `tiling_assembly.repair` orders; they are no longer placed until the winner puts them back.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from std_msgs.msg import String

from auction_node.auction import AuctionBook, Award
from auction_node.delivery import AnnouncementRepeater, AwardDelivery
from auction_node.liveness import Liveness
from auction_node.mismatch import MISSING, PRESENT, UNDETERMINED, Misfit, MismatchDetector, UnconfirmedReports
from tiling_assembly.messages import pose_of, structure_from_msg
from tiling_assembly.repair import plan_repair
from tiling_assembly.scan_freshness import RepeatFilter
from tiling_assembly.structure import Structure as StructureModel
from tiling_assembly.structure import StructureError
from tiling_assembly_msgs.msg import (
    AssemblyPlan,
    AuctionAcceptance,
    AuctionAnnouncement,
    AuctionAward,
    AuctionBid,
    AuctioneerStatus,
    PlacementReport,
    RobotStatus,
    Structure,
    TileState,
    TileStateArray,
)
from tiling_assembly_msgs.srv import Replan
from tiling_ros import team_topics as topics
from tiling_ros.parameters import declare_settings, setting
from tiling_ros.spinning import run_node
from tiling_ros.stamps import stamp_from_nanoseconds, stamp_from_seconds, stamp_to_seconds

DUE_CHECK_PERIOD = 0.05  # s (node clock): deadlines are seconds long; the simulated /clock steps this often
SENSING = {TileState.PRESENT: PRESENT, TileState.MISSING: MISSING}  # anything else: undetermined
REASONS = {
    AuctionAnnouncement.REASON_MISSING: "missing",
    AuctionAnnouncement.REASON_ROBOT_LOST: "its robot was lost",
    AuctionAnnouncement.REASON_GAVE_UP: "given up",
    AuctionAnnouncement.REASON_FOUND_MISSING: "missing, found by a robot",
    AuctionAnnouncement.REASON_MISPLACED: "lying wrong: repair",
}


@dataclass(frozen=True)
class AuctionSettings:
    """The parameters of auction_node (config/auction_node.yaml), with their defaults."""

    confirmations: int = setting(2, "Scans that must call a placed tile missing, none present between (paper: 1).")
    confirmation_view_change: float = setting(
        0.15, "m between the camera positions of two scans confirming a missing tile (0: any scans).")
    misplaced_agreement_shift: float = setting(
        0.02, "m: scans confirming a misplaced tile must find it moved this alike (and of the same wrong type).")
    misplaced_agreement_turn: float = setting(
        10.0, "deg: scans confirming a misplaced tile must find it turned this alike.")
    bid_window: float = setting(2.0, "s (node clock) from an announcement to its deadline.")
    liveness_timeout: float = setting(1.5, "s of wall-clock time without a heartbeat before a robot is lost.")
    acceptance_timeout: float = setting(
        10.0, "s of wall-clock time without acceptance from a winner still heard before its tile is auctioned "
        "again (a lost winner's tile goes back at once).")
    resend_period: float = setting(
        0.05, "s of wall-clock time between copies of an unanswered announcement or award.")
    lost_tile_grace: float = setting(
        60.0, "s (node clock) the tile in a lost robot's hands stays its own before it is auctioned (out of "
        "reach, the robot may be placing it).")
    status_period: float = setting(
        0.2, "s of wall-clock time between two /auction/status heartbeats; robots' liveness is checked as often.")
    reopen_delay: float = setting(5.0, "s (node clock) before an auction nobody bid in is reopened.")
    lost_robot_policy: str = setting("replan", "'replan' (planner's /replan service) or 'auction' per tile.")
    robots_find_missing: bool = setting(
        True, "A support a robot found absent when placing on it is missing (false: only scans decide).")
    unconfirmed_report_timeout: float = setting(
        60.0, "s (node clock): with robots_find_missing false, a support a robot found absent that no scan has "
        "found missing by then is treated as missing, so the robot does not wait forever.")


class AuctionNode(Node):
    def __init__(self) -> None:
        super().__init__("auction_node")
        settings = self.settings = declare_settings(self, AuctionSettings)
        self.detector = MismatchDetector(
            confirmations=int(settings.confirmations),
            min_view_change=float(settings.confirmation_view_change),
            misfit_shift=float(settings.misplaced_agreement_shift),
            misfit_turn=math.radians(float(settings.misplaced_agreement_turn)),
        )
        self.book = AuctionBook(bid_window=float(settings.bid_window))
        self.liveness = Liveness(timeout=float(settings.liveness_timeout))
        resend_period = float(settings.resend_period)
        self.delivery = AwardDelivery(resend_period, float(settings.acceptance_timeout))
        self.repeater = AnnouncementRepeater(resend_period)
        if resend_period <= 0 or self.delivery.give_up_after <= 0:
            raise ValueError("resend_period and acceptance_timeout must be positive")
        self.reopen_delay = float(settings.reopen_delay)
        self.lost_robot_policy = str(settings.lost_robot_policy)
        self.robots_find_missing = bool(settings.robots_find_missing)
        self.unconfirmed = UnconfirmedReports(float(settings.unconfirmed_report_timeout))
        if self.unconfirmed.timeout <= 0:
            raise ValueError("unconfirmed_report_timeout must be positive")
        if self.lost_robot_policy not in ("replan", "auction"):
            raise ValueError(f"lost_robot_policy must be 'replan' or 'auction', got '{self.lost_robot_policy}'")
        if self.book.bid_window <= 0 or self.liveness.timeout <= 0:
            raise ValueError("bid_window and liveness_timeout must be positive")
        if self.detector.confirmations < 1 or self.detector.min_view_change < 0:
            raise ValueError("confirmations must be at least 1 and confirmation_view_change not negative")
        if self.detector.misfit_shift < 0 or self.detector.misfit_turn < 0:
            raise ValueError("misplaced_agreement_shift and misplaced_agreement_turn must not be negative")

        self.repeats = RepeatFilter()
        self.structure: StructureModel | None = None
        self.status: dict[str, RobotStatus] = {}
        self.detected_wall: dict[int, float] = {}  # tile -> wall time its mismatch was detected
        self.announcements: dict[int, AuctionAnnouncement] = {}  # open auction id -> its announcement
        self.reopen: list[tuple[float, int, int]] = []  # (node time, tile, reason)
        self.plan_revision = 0
        self.in_lost_hands: dict[str, tuple[int, float]] = {}  # lost robot -> (tile in its hands, node time)
        self.lost_tile_grace = float(settings.lost_tile_grace)
        self.under_repair: set[int] = set()  # tiles auctioned for repair and not yet placed again
        self.told_deferred: dict[int, int] = {}  # tile -> the wrong tile on or under it it last waited for

        self.announce_pub = topics.ANNOUNCEMENTS.publisher(self)
        self.award_pub = topics.AWARDS.publisher(self)
        self.decision_pub = topics.DECISIONS_LOG.publisher(self)
        self.status_pub = topics.AUCTIONEER_STATUS.publisher(self)
        topics.PLAN.subscribe(self, self.on_plan)
        topics.STRUCTURE.subscribe(self, self.on_structure)
        topics.PLACEMENT_REPORTS.subscribe(self, self.on_report)
        topics.TILE_STATES.subscribe(self, self.on_tile_states)
        topics.BIDS.subscribe(self, self.on_bid)
        topics.ACCEPTANCES.subscribe(self, self.on_acceptance)
        topics.ROBOT_STATUS.subscribe(self, self.on_status)
        self.replan_client = self.create_client(Replan, "/replan")
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        # deadlines, reopenings and graces are in node time: checked as that clock moves (in the
        # simulation, as /clock moves, whatever the host's load), not on a fast wall-clock tick
        # whose every wake-up costs the executor a pass over all its entities
        self.create_timer(DUE_CHECK_PERIOD, self.check_due)
        self.create_timer(float(settings.status_period), self.heartbeat, clock=steady)
        # copies go out every resend_period of wall time, only while something waits for an answer
        self.resend_timer = self.create_timer(resend_period, self.resend_unanswered, clock=steady)
        self.resend_timer.cancel()
        self.get_logger().info("auction node ready")

    # --- helpers ------------------------------------------------------------------------------
    def now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def decide(self, line: str, error: bool = False) -> None:
        if error:
            self.get_logger().warn(line)
        else:
            self.get_logger().info(line)
        self.decision_pub.publish(String(data=line))

    def announce(self, tile_id: int, reason: int, exclude: str = "", only: str = "") -> None:
        """Open an auction for `tile_id` among the robots alive, but `exclude` (unless it is the only
        one), or `only` that robot when it is alive."""
        if self.structure is None or tile_id not in self.structure.tiles:
            return
        resting = self.resting_on(tile_id) if reason == AuctionAnnouncement.REASON_MISPLACED else []
        alive = self.liveness.alive()
        invited = [only] if only in alive else [r for r in alive if r != exclude] or alive
        if not invited:
            self.decide(f"tile {tile_id} ({REASONS[reason]}): no robot alive to bid; retrying later", error=True)
            self.reopen.append((self.now() + self.reopen_delay, tile_id, reason))
            return
        auction = self.book.open(tile_id, reason, self.now(), invited)
        if auction is None:
            return
        tile = self.structure.tiles[tile_id]
        msg = AuctionAnnouncement(
            auction_id=auction.auction_id, tile_id=tile_id, tile_type=tile.type_name, reason=reason,
            bidders=sorted(auction.invited), resting_on_it=resting,
        )
        for above in resting:  # they come off with it
            self.detector.unplaced(above)
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.structure.frame_id
        msg.tile_pose = pose_of(tile)
        msg.deadline = stamp_from_nanoseconds(int(auction.deadline * 1e9))
        self.announce_pub.publish(msg)
        self.announcements[auction.auction_id] = msg
        self.repeater.sent(auction.auction_id, time.monotonic())
        self.expect_answers()
        verbs = "rests on it and comes" if len(resting) == 1 else "rest on it and come"
        taken_off = f"; {', '.join(map(str, resting))} {verbs} off first" if resting else ""
        self.decide(
            f"auction {auction.auction_id} opened for tile {tile_id} ({tile.type_name}, {REASONS[reason]}{taken_off}); "
            f"bidders: {', '.join(sorted(auction.invited))}"
        )

    def resting_on(self, tile_id: int) -> list[int]:
        """The placed tiles resting on `tile_id`, directly or through others, top down (`repair`)."""
        assert self.structure is not None
        placed = {*self.detector.placed_tiles(), tile_id}
        return list(plan_repair(self.structure, tile_id, placed).taken_off)

    def repair(self, tile_id: int, why: str) -> None:
        """Auction the repair of `tile_id`, found lying wrong, unless one is under way.

        A tile called missing before is there after all: its re-placement, if still auctioned, is
        withdrawn, and a robot that holds it (won it, not yet placed it) is the one to repair it,
        since it goes there with the tile anyway.
        """
        if tile_id in self.under_repair:
            return
        self.under_repair.add(tile_id)
        self.detector.lies_wrong(tile_id)
        self.detected_wall[tile_id] = time.time()
        withdrawn = self.withdraw_placement(tile_id)
        holder = self.book.held_by.get(tile_id, "")
        holder = holder if holder in self.liveness.alive() else ""
        instead = f"; auction {withdrawn} to place it again is withdrawn" if withdrawn else ""
        by_holder = f"; {holder}, which is to place it again, does it" if holder else ""
        self.decide(f"tile {tile_id} lies wrong ({why}): repairing it{instead}{by_holder}")
        self.announce(tile_id, AuctionAnnouncement.REASON_MISPLACED, only=holder)

    def withdraw_placement(self, tile_id: int) -> int:
        """Withdraw the open auction (or the reopening due) to place `tile_id`; the auction id, or 0."""
        self.reopen = [entry for entry in self.reopen if entry[1] != tile_id]
        auction = self.book.withdraw(tile_id)
        if auction is None:
            return 0
        self.announcements.pop(auction.auction_id, None)
        return auction.auction_id

    # --- inputs -------------------------------------------------------------------------------
    def on_structure(self, msg: Structure) -> None:
        try:
            self.structure = structure_from_msg(msg, "/structure")
        except StructureError as error:
            self.get_logger().error(f"ignoring the structure on /structure: {error}")
            return
        self.detector.above = self.structure.resting_above

    def on_report(self, msg: PlacementReport) -> None:
        if msg.outcome == PlacementReport.OUTCOME_PLACED:
            self.detector.placed(msg.tile_id, stamp_to_seconds(msg.header.stamp))
            self.under_repair.discard(msg.tile_id)
            self.book.settled(msg.tile_id)
        elif msg.outcome == PlacementReport.OUTCOME_REMOVED:
            self.detector.taken_off(msg.tile_id)
        elif msg.outcome == PlacementReport.OUTCOME_BLOCKED:
            for wrong in msg.wrong_tiles:
                self.repair(wrong, f"{msg.robot_name} found it in the way when placing tile {msg.tile_id}")
        elif msg.outcome == PlacementReport.OUTCOME_FAILED:
            self.detector.unplaced(msg.tile_id)
            self.under_repair.discard(msg.tile_id)  # a robot placing it will find it in the way again
            self.book.settled(msg.tile_id)
            self.decide(f"{msg.robot_name} gave up tile {msg.tile_id}: {msg.reason}", error=True)
            self.announce(msg.tile_id, AuctionAnnouncement.REASON_GAVE_UP, exclude=msg.robot_name)
        elif msg.outcome == PlacementReport.OUTCOME_SUPPORT_MISSING:
            at = stamp_to_seconds(msg.header.stamp)
            for support in msg.missing_supports:
                if self.detector.q.get(support, 0) != 1:
                    continue  # found missing already, or never placed
                if self.robots_find_missing:
                    self.robot_found_missing(support, at, msg.robot_name, msg.tile_id)
                else:
                    self.unconfirmed.report(support, msg.robot_name, msg.tile_id, at)
                    self.decide(
                        f"{msg.robot_name} found tile {support} absent when placing tile {msg.tile_id} on it; "
                        f"waiting up to {self.unconfirmed.timeout:g} s for a scan to confirm"
                    )

    def robot_found_missing(self, support: int, at: float, robot: str, tile_id: int, waited: bool = False) -> None:
        if not self.detector.found_absent(support, at):
            return  # found missing already (by a scan), or placed again since
        self.detected_wall[support] = time.time()
        unconfirmed = f"; no scan confirmed it within {self.unconfirmed.timeout:g} s" if waited else ""
        self.decide(f"tile {support} was placed but {robot} found it missing when placing tile {tile_id} on it"
                    f"{unconfirmed}")
        self.announce(support, AuctionAnnouncement.REASON_FOUND_MISSING)

    def on_tile_states(self, msg: TileStateArray) -> None:
        if msg.problem:  # a scan that gave no states says nothing about any tile
            return
        detected = time.time()
        fresh = self.repeats.fresh_states(msg.states, msg.robot_name)
        sensing = {s.tile_id: SENSING.get(s.state, UNDETERMINED) for s in msg.states if s.tile_id in fresh}
        view = (msg.camera_pose.position.x, msg.camera_pose.position.y)
        at = stamp_to_seconds(msg.header.stamp)
        for tile_id in self.detector.sensed(sensing, at, view):
            self.detected_wall[tile_id] = detected
            self.decide(f"tile {tile_id} was placed but the scan says missing (q * q^s = -1)")
            self.announce(tile_id, AuctionAnnouncement.REASON_MISSING)
        self.tell_deferred({t for t, value in sensing.items() if value == MISSING})
        verdicts = {s.tile_id: misfit(s) if s.state == TileState.MISPLACED else False for s in msg.states
                    if s.tile_id in fresh and s.state in (TileState.PRESENT, TileState.MISPLACED)}
        offsets = {s.tile_id: s for s in msg.states}
        flagged = self.detector.flagged(verdicts, at, view)
        self.tell_deferred({t for t, wrong in verdicts.items() if wrong})
        for tile_id in flagged:
            self.repair(tile_id, f"scans from {self.detector.confirmations} camera positions say misplaced, last "
                                 f"{how_it_lies(offsets[tile_id])}")

    def tell_deferred(self, called_wrong: set[int]) -> None:
        """One line the first time a scan's word against a tile waits for the wrong tile on it."""
        for tile_id, wrong in self.detector.deferred.items():
            if tile_id in called_wrong and self.told_deferred.get(tile_id) != wrong:
                self.told_deferred[tile_id] = wrong
                on_it = wrong in self.detector.above.get(tile_id, ())
                where = (f"tile {wrong} on it lies wrong (or may)" if on_it
                         else f"it rests on tile {wrong}, which lies wrong")
                self.decide(f"tile {tile_id} looks wrong or missing, but {where}: "
                            f"judged again once that tile is judged or repaired")

    def on_plan(self, msg: AssemblyPlan) -> None:
        self.plan_revision = max(self.plan_revision, msg.revision)

    def on_bid(self, msg: AuctionBid) -> None:
        auction = self.book.open_auctions.get(msg.auction_id)
        if auction is not None and auction.bids.get(msg.robot_name) == msg.bid:
            return  # a copy: the robot answered a repeated announcement
        refused = self.book.bid(msg.auction_id, msg.robot_name, msg.bid, self.now())
        if refused:
            self.get_logger().warn(f"bid refused: {refused}")
            return
        self.close_auctions()

    def on_acceptance(self, msg: AuctionAcceptance) -> None:
        pending = self.delivery.accepted(msg.auction_id)
        if pending is not None and msg.award_latency > 0:
            self.get_logger().info(
                f"{msg.robot_name} accepted tile {msg.tile_id} {msg.award_latency * 1000:.1f} ms after detection"
            )

    def on_status(self, msg: RobotStatus) -> None:
        self.status[msg.robot_name] = msg
        self.delivery.taken_up(msg.robot_name, [msg.current_tile, *msg.remaining_tiles])
        if self.liveness.heard(msg.robot_name, time.monotonic()):
            self.robot_back(msg.robot_name)

    def publish_status(self) -> None:
        status = AuctioneerStatus(
            plan_revision=self.plan_revision, alive_robots=self.liveness.alive(),
            lost_robots=sorted(self.liveness.lost),
        )
        status.header.stamp = self.get_clock().now().to_msg()
        self.status_pub.publish(status)

    # --- time-driven --------------------------------------------------------------------------
    def heartbeat(self) -> None:
        """Robots silent for liveness_timeout are lost; then the auctioneer's own heartbeat."""
        for robot in self.liveness.newly_lost(time.monotonic()):
            self.robot_lost(robot)
        self.publish_status()

    def resend_unanswered(self) -> None:
        self.repeat_unanswered(time.monotonic())
        if not self.book.open_auctions and not self.delivery.pending:
            self.resend_timer.cancel()

    def expect_answers(self) -> None:
        """An announcement or an award went out: copies follow until it is answered."""
        if self.resend_timer.is_canceled():
            self.resend_timer.reset()

    def check_due(self) -> None:
        """What the node clock has made due: auctions at their deadline, tiles in lost hands past
        their grace, unconfirmed reports past their wait, auctions to reopen."""
        self.close_auctions()
        self.give_up_lost_hands()
        for support, at, robot, tile_id in self.unconfirmed.due(self.now()):
            self.robot_found_missing(support, at, robot, tile_id, waited=True)
        due = [entry for entry in self.reopen if entry[0] <= self.now()]
        self.reopen = [entry for entry in self.reopen if entry[0] > self.now()]
        for _, tile_id, reason in due:
            self.announce(tile_id, reason)

    def repeat_unanswered(self, wall: float) -> None:
        waiting = {a.auction_id: not a.invited <= set(a.bids) for a in self.book.open_auctions.values()}
        for auction_id in self.repeater.due_again(wall, waiting):
            self.announce_pub.publish(self.announcements[auction_id])
        for pending in self.delivery.due_again(wall):
            self.award_pub.publish(self.award_message(pending.award, pending.detected_wall))
        for pending in self.delivery.overdue(wall):
            self.decide(
                f"{pending.award.winner} did not accept tile {pending.award.tile_id} "
                f"(auction {pending.award.auction_id}) in {self.delivery.give_up_after:g} s; auctioning it again",
                error=True,
            )
            self.announce(pending.award.tile_id, pending.reason, exclude=pending.award.winner)

    def close_auctions(self) -> None:
        reasons = {a.auction_id: a.reason for a in self.book.open_auctions.values()}
        for award in self.book.close_ready(self.now()):
            self.publish_award(award, reasons[award.auction_id])

    def publish_award(self, award: Award, reason: int) -> None:
        self.announcements.pop(award.auction_id, None)
        missing = (AuctionAnnouncement.REASON_MISSING, AuctionAnnouncement.REASON_FOUND_MISSING,
                   AuctionAnnouncement.REASON_MISPLACED)
        detected = self.detected_wall.pop(award.tile_id, 0.0) if reason in missing else 0.0
        self.award_pub.publish(self.award_message(award, detected))
        self.decide(award.decision, error=not award.winner)
        if award.winner:
            self.delivery.sent(award, reason, detected, time.monotonic())
            self.expect_answers()
        else:
            self.reopen.append((self.now() + self.reopen_delay, award.tile_id, reason))

    def award_message(self, award: Award, detected: float) -> AuctionAward:
        msg = AuctionAward(
            auction_id=award.auction_id, tile_id=award.tile_id, winner=award.winner,
            winning_bid=award.winning_bid if award.winner else 0.0, bidders=list(award.bidders),
            bids=list(award.bids), decision=award.decision,
        )
        msg.header.stamp = self.get_clock().now().to_msg()
        if detected:
            msg.detection_wall_stamp = stamp_from_seconds(detected)
        return msg

    def robot_lost(self, robot: str) -> None:
        """Its tiles go to the others, except the one in its hands: a robot out of reach may be
        placing it right now; that tile goes to auction only if it is not heard of for
        `lost_tile_grace` (two robots must never place the same tile)."""
        self.book.forget_bidder(robot)
        last = self.status.get(robot)
        in_hand = last.current_tile if last is not None else 0
        tiles = [t for t in (last.remaining_tiles if last is not None else []) if t != in_hand]
        kept = f"; tile {in_hand} in its hands stays its own for {self.lost_tile_grace:g} s" if in_hand else ""
        self.decide(
            f"{robot} lost (no heartbeat for {self.liveness.timeout:.1f} s); its unplaced tiles "
            f"{tiles} go to {', '.join(self.liveness.alive()) or 'nobody'} by {self.lost_robot_policy}{kept}",
            error=True,
        )
        if in_hand:
            self.in_lost_hands[robot] = (in_hand, self.now() + self.lost_tile_grace)
        unaccepted = self.delivery.winner_lost(robot)
        if not self.liveness.alive():
            return
        for pending in unaccepted:
            self.announce(pending.award.tile_id, pending.reason, exclude=robot)
        if self.lost_robot_policy == "replan" and self.replan_client.service_is_ready():
            self.request_replan(f"losing {robot}", tiles)
        else:
            for tile_id in tiles:
                self.announce(tile_id, AuctionAnnouncement.REASON_ROBOT_LOST)

    def robot_back(self, robot: str) -> None:
        """A lost robot is heard again: its old tiles are others' now; a replan gives it a share."""
        self.in_lost_hands.pop(robot, None)
        if self.lost_robot_policy == "replan" and self.replan_client.service_is_ready():
            self.decide(f"{robot} is back: it takes part in auctions again, and a replan gives it a share")
            self.request_replan(f"{robot} came back", [])
        else:
            self.decide(f"{robot} is back: it takes part in auctions again")

    def give_up_lost_hands(self) -> None:
        """Tiles in the hands of robots lost for `lost_tile_grace` and not placed: to auction."""
        placed = set(self.detector.placed_tiles())
        for robot, (tile_id, due) in list(self.in_lost_hands.items()):
            if self.now() < due:
                continue
            del self.in_lost_hands[robot]
            if tile_id not in placed:
                self.decide(f"{robot} is still lost after {self.lost_tile_grace:g} s: tile {tile_id} it had in "
                            "hand goes to auction", error=True)
                self.announce(tile_id, AuctionAnnouncement.REASON_ROBOT_LOST)

    def request_replan(self, why: str, tiles: list[int]) -> None:
        in_flight = [s.current_tile for r, s in self.status.items() if r in self.liveness.alive() and s.current_tile]
        in_flight += [tile_id for tile_id, _ in self.in_lost_hands.values()]
        request = Replan.Request(
            placed_tile_ids=sorted(set(self.detector.placed_tiles()) | set(in_flight)),
            available_robots=self.liveness.alive(),
        )
        future = self.replan_client.call_async(request)

        def done(f) -> None:  # type: ignore[no-untyped-def]
            response = f.result()
            if response is not None and response.success:
                self.decide(
                    f"replanned after {why}: plan revision {response.plan.revision} for "
                    f"{', '.join(t.robot_name for t in response.plan.tasks)}"
                )
                return
            reason = response.message if response is not None else "no answer"
            self.decide(f"replan after {why} failed ({reason}); auctioning the tiles {tiles}", error=True)
            for tile_id in tiles:
                self.announce(tile_id, AuctionAnnouncement.REASON_ROBOT_LOST)

        future.add_done_callback(done)


def misfit(found: TileState) -> Misfit:
    """How a scan found a misplaced tile lying."""
    return Misfit(found.offset_x, found.offset_y, found.offset_yaw, found.seen_type)


def how_it_lies(found: TileState) -> str:
    """What the scan found at a misplaced tile's place, in words."""
    if found.seen_type:
        return f"a {found.seen_type} in its place"
    return (f"off by {100 * (found.offset_x ** 2 + found.offset_y ** 2) ** 0.5:.1f} cm, "
            f"{math.degrees(found.offset_yaw):+.0f} deg")


def main(args: list[str] | None = None) -> int:
    return run_node(AuctionNode, (ValueError,), args=args, error_prefix="auction_node")


if __name__ == "__main__":
    sys.exit(main())
