"""assembly_node: one assembly robot of the team (paper sections 2.1, 2.3 and 3.1).

A thin adapter around `executor.PlanExecutor` and `bidding.compute_bid`. Runs in the robot's
namespace (`/robot1`, …). In: the latched `/structure` and `/plan`, `/placement_reports` of the
whole team, `/auction/announcements` and `/auction/awards`. Out: the `place_tile` action goals to
its robot (real M3 driver or simulated robot), `/placement_reports`, `/auction/bids`,
`/auction/acceptances`, and a `/robot_status` heartbeat on the wall clock (so that a robot whose
process hangs or dies is noticed even while simulated time runs fast). It hears the auction node's
`/auction/status` and starts no new tile while cut off from it (`team_contact`); a repeated
announcement is answered with the same bid, a repeated award with the same acceptance.

Beyond the paper: a placement refused because tiles lie wrong in the way is reported
(OUTCOME_BLOCKED, a sensor as good as a scan) and the tile waits for their repair; a repair won in an
auction (REASON_MISPLACED) takes tiles off with the robot's `remove_tile` action (reported
OUTCOME_REMOVED) and places them back right. A robot with nothing left to place drives home with its
base's `navigate_to` action (`parking`), out of the scanning robots' view.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

from action_msgs.msg import GoalStatus
from geometry_msgs.msg import Point, PoseStamped
from rclpy.action import ActionClient
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from assembly_node.bidding import compute_bid, compute_repair_bid
from assembly_node.executor import Outcome, PlanExecutor, StepKind
from assembly_node.parking import Parking, facing
from assembly_node.team_contact import TeamContact
from tiling_assembly.messages import pose_of, structure_from_msg
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly.time_model import TimeModel
from tiling_assembly_msgs.action import NavigateTo, PlaceTile, RemoveTile
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
)
from tiling_ros import team_topics as topics
from tiling_ros.parameters import declare_settings, setting
from tiling_ros.spinning import run_node
from tiling_ros.stamps import is_zero, stamp_to_seconds

_TIMES = TimeModel()
# s a found place_tile server must stay reachable before a goal goes to it: sent the moment the
# server is found, a goal can run while its acceptance is lost (the server has not yet found this
# client's reader), and the tile then waits for the action timeout (seen once in a demo)
SERVER_SETTLE = 1.0


@dataclass(frozen=True)
class AssemblySettings:
    """The parameters of assembly_node (config/assembly_node.yaml), with their defaults."""

    robot_name: str = setting("", "Name in plans and auctions; empty: the namespace without '/'.")
    structure_file: str = setting("", "Structure YAML to use before /structure arrives; empty: wait.")
    pick_time: float = setting(_TIMES.pick_time, "Time model: s to find and grasp a tile at its cache.")
    place_time: float = setting(_TIMES.place_time, "Time model: s to place a tile.")
    travel_speed: float = setting(_TIMES.travel_speed, "Time model: mean base speed between cache and structure, m/s.")
    cache_standoff: float = setting(_TIMES.cache_standoff, "Time model: m a base stops short of a parts cache.")
    approach_distance: float = setting(
        _TIMES.approach_distance, "Time model: m from a tile's centre to where a base stops to place it.")
    base_size: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        list(_TIMES.base_size), "Time model: x and y size of a robot base's footprint (m).")
    base_clearance: float = setting(_TIMES.base_clearance, "Time model: m a base keeps from every tile.")
    cache_crowding: float = setting(
        _TIMES.cache_crowding, "Time model: s a pick costs for every robot of the plan beyond one per cache in use.")
    stop_crowding: float = setting(
        _TIMES.stop_crowding, "Time model: s a pick costs for every other robot of the plan times the share of the "
        "structure's stops a base at one overlaps (the larger of this and the caches' crowding counts).")
    weight_supported: float = setting(30.0, "A in b = w - A*c + B*d: s per own tile the missing one supports.")
    weight_distance: float = setting(10.0, "B in b = w - A*c + B*d: s per metre from own cache to the tile.")
    bid_in_auctions: bool = setting(True, "Take part in auctions; false: never bid (the robot keeps its own task).")
    max_attempts: int = setting(3, "Place actions per tile before giving it up for auction.")
    retry_delay: float = setting(5.0, "s (node clock) to wait before retrying a failed placement.")
    strict_order: bool = setting(False, "Wait on the next planned tile instead of placing a later ready one.")
    action_timeout: float = setting(900.0, "s (node clock) a place action may take before it counts as failed.")
    heartbeat_period: float = setting(0.2, "s of wall-clock time between two /robot_status heartbeats.")
    auctioneer_timeout: float = setting(
        1.5, "s of wall-clock time without /auction/status after which the robot finishes its tile and starts no "
        "new one (its tiles may be given to others).")
    cache_types: list[str] = setting(  # noqa: RUF009 - a field() with a default_factory
        [""], "Tile types with a cache of this robot's own (parallel to cache_xy).")
    cache_xy: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.0], "x1, y1, x2, y2, ... of this robot's own caches in map (m).")
    park_when_done: bool = setting(
        True, "With nothing left to place, drive home (navigate_to), out of the scanning robots' view.")
    home_xy: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        [0.0], "x, y in map (m) where the robot waits with nothing to place; fewer than 2 numbers: where the "
        "overhead cameras first saw it.")


class AssemblyNode(Node):
    def __init__(self) -> None:
        super().__init__("assembly_node")
        settings = self.settings = declare_settings(self, AssemblySettings)
        self.robot_name = self._robot_name()
        self.time_model = TimeModel(
            pick_time=settings.pick_time, place_time=settings.place_time, travel_speed=settings.travel_speed,
            cache_standoff=settings.cache_standoff, approach_distance=settings.approach_distance,
            base_size=tuple(settings.base_size), base_clearance=settings.base_clearance,
            cache_crowding=settings.cache_crowding, stop_crowding=settings.stop_crowding,
        )
        self.team_size = 1  # robots of the latest plan: they crowd the caches (TimeModel.for_team)
        self.weight_supported = float(settings.weight_supported)
        self.weight_distance = float(settings.weight_distance)
        self.max_attempts = int(settings.max_attempts)
        self.bid_in_auctions = bool(settings.bid_in_auctions)
        self.retry_delay = float(settings.retry_delay)
        self.strict_order = bool(settings.strict_order)
        self.action_timeout = float(settings.action_timeout)
        self.own_caches = self._cache_overrides()
        self.parking = Parking(home=self._home()) if settings.park_when_done else None
        self.parking_handle = None  # the navigate_to goal under way (None: none, or its response pending)
        self.parking_since: float | None = None  # wall time the drive home was sent; None: no drive
        self.navigate_lost_since: float | None = None  # wall time the navigate_to server went away
        self.contact = TeamContact(self.robot_name, float(settings.auctioneer_timeout))
        self.bids_made: dict[int, AuctionBid] = {}  # auction id -> the bid sent
        self.acceptances: dict[int, AuctionAcceptance] = {}  # auction id -> the acceptance sent
        self.repairs: dict[int, AuctionAnnouncement] = {}  # auction id -> a repair announcement bid in
        self.standing_at: tuple[float, float] | None = None  # the latest view of the base (overhead, feedback)

        self.executor_state: PlanExecutor | None = None
        self.pending_plan: AssemblyPlan | None = None
        # placements and missing tiles heard before the structure (discovery can deliver it late)
        self.early_news: list[tuple[bool, int]] = []  # (placed, tile id), in arrival order
        self.retry_after = 0.0  # s of node time before the next attempt may start
        self.last_wait_logged: tuple[int, ...] = ()
        self.goal_handle = None
        self.goal_sent_at = 0.0  # node time the running place action was sent
        self.server_found_at: float | None = None  # wall time the action server was found
        self.server_lost_since: float | None = None  # wall time the action server went away

        self.report_pub = topics.PLACEMENT_REPORTS.publisher(self)
        self.bid_pub = topics.BIDS.publisher(self)
        self.accept_pub = topics.ACCEPTANCES.publisher(self)
        self.status_pub = topics.ROBOT_STATUS.publisher(self)
        topics.STRUCTURE.subscribe(self, self.on_structure)
        topics.PLAN.subscribe(self, self.on_plan)
        topics.PLACEMENT_REPORTS.subscribe(self, self.on_report)
        topics.ANNOUNCEMENTS.subscribe(self, self.on_announcement)
        topics.AWARDS.subscribe(self, self.on_award)
        topics.AUCTIONEER_STATUS.subscribe(self, self.on_auctioneer_status)
        self.create_subscription(PoseStamped, "overhead_pose", self.on_overhead_pose, 10)
        self.place_client = ActionClient(self, PlaceTile, "place_tile")
        self.remove_client = ActionClient(self, RemoveTile, "remove_tile")
        self.navigate_client = ActionClient(self, NavigateTo, "navigate_to")

        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self.create_timer(float(settings.heartbeat_period), self.publish_status, clock=steady)
        self.create_timer(0.25, self.step, clock=steady)

        if settings.structure_file:
            self._set_structure(load_structure(settings.structure_file))
        self.get_logger().info(f"{self.robot_name} ready; waiting for the plan on /plan")

    def _robot_name(self) -> str:
        name = self.settings.robot_name or self.get_namespace().strip("/")
        if not name or "/" in name:
            raise ValueError(
                f"robot_name is '{name}': run the node in a robot namespace (e.g. /robot1) or set robot_name"
            )
        return name

    def _cache_overrides(self) -> dict[str, tuple[float, float]]:
        types = [t for t in self.settings.cache_types if t]
        xy = list(self.settings.cache_xy) if types else []
        if len(xy) != 2 * len(types):
            raise ValueError(f"cache_xy needs 2 numbers per cache type ({len(types)} types), got {len(xy)}")
        return {t: (float(xy[2 * k]), float(xy[2 * k + 1])) for k, t in enumerate(types)}

    def _home(self) -> tuple[float, float] | None:
        xy = list(self.settings.home_xy)
        if len(xy) < 2:
            return None
        if len(xy) != 2:
            raise ValueError(f"home_xy needs x and y, got {len(xy)} numbers")
        return float(xy[0]), float(xy[1])

    def cache_of(self, type_name: str) -> tuple[float, float] | None:
        assert self.executor_state is not None
        return self.own_caches.get(type_name, self.executor_state.structure.caches.get(type_name))

    # --- inputs -------------------------------------------------------------------------------
    def _set_structure(self, structure) -> None:  # type: ignore[no-untyped-def]
        if self.executor_state is not None and self.executor_state.structure.name == structure.name:
            return
        self.executor_state = PlanExecutor(
            self.robot_name, structure, max_attempts=self.max_attempts, strict_order=self.strict_order
        )
        for placed, tile_id in self.early_news:
            if placed:
                self.executor_state.note_placed(tile_id)
            else:
                self.executor_state.note_missing(tile_id)
        self.early_news.clear()
        if self.pending_plan is not None:
            plan, self.pending_plan = self.pending_plan, None
            self.on_plan(plan)

    def on_structure(self, msg: Structure) -> None:
        try:
            self._set_structure(structure_from_msg(msg, "/structure"))
        except StructureError as error:
            self.get_logger().error(f"ignoring the structure on /structure: {error}")

    def team_model(self) -> TimeModel:
        """The time model of this team on this structure, as the planner made the plan with (w_i)."""
        assert self.executor_state is not None
        return self.time_model.for_team(self.executor_state.structure, self.team_size)

    def on_plan(self, msg: AssemblyPlan) -> None:
        if self.executor_state is None:
            self.pending_plan = msg
            return
        task = next((t for t in msg.tasks if t.robot_name == self.robot_name), None)
        tiles = list(task.tile_ids) if task is not None else []
        self.team_size = max(len(msg.tasks), 1)
        if self.executor_state.adopt_plan(msg.revision, tiles):
            self.get_logger().info(
                f"plan revision {msg.revision}: {len(self.executor_state.remaining)} tiles to place "
                f"{list(self.executor_state.remaining)}"
            )
            self.step()

    def on_report(self, msg: PlacementReport) -> None:
        if msg.outcome not in (PlacementReport.OUTCOME_PLACED, PlacementReport.OUTCOME_REMOVED):
            return
        placed = msg.outcome == PlacementReport.OUTCOME_PLACED
        if self.executor_state is None:
            self.early_news.append((placed, msg.tile_id))
            return
        if placed:
            self.executor_state.note_placed(msg.tile_id)
        else:  # a repair took it off: it holds nothing up until it is back
            self.executor_state.note_missing(msg.tile_id)
        self.step()

    def on_overhead_pose(self, msg: PoseStamped) -> None:
        self.saw_robot_at(msg)

    def on_feedback(self, message) -> None:  # type: ignore[no-untyped-def]
        """A place or remove action's feedback: where the base is (the overhead cameras may publish
        only now and then, as the simulated ones do at each scan)."""
        self.saw_robot_at(message.feedback.robot_pose)

    def saw_robot_at(self, msg: PoseStamped) -> None:
        if not msg.header.frame_id:
            return  # the robot does not know its pose yet
        self.standing_at = (msg.pose.position.x, msg.pose.position.y)
        if self.parking is not None:
            self.parking.saw_robot_at(self.standing_at)

    def on_auctioneer_status(self, msg: AuctioneerStatus) -> None:
        self.contact.heard(time.monotonic(), msg.plan_revision, msg.lost_robots)

    def on_announcement(self, msg: AuctionAnnouncement) -> None:
        if msg.auction_id in self.bids_made:  # a copy: our bid may have been lost
            self.bid_pub.publish(self.bids_made[msg.auction_id])
            return
        state = self.executor_state
        repair = msg.reason == AuctionAnnouncement.REASON_MISPLACED
        # a tile lying wrong, and the tiles that come off with it, hold nothing up as planned
        not_there = [msg.tile_id, *msg.resting_on_it] if repair else [msg.tile_id]
        missing = repair or msg.reason in (AuctionAnnouncement.REASON_MISSING,
                                           AuctionAnnouncement.REASON_FOUND_MISSING)
        if state is None:
            if missing:
                self.early_news += [(False, tile) for tile in not_there]
            return
        if missing:
            for tile in not_there:
                state.note_missing(tile)
        if not self.bid_in_auctions or self.robot_name not in msg.bidders:
            return
        if msg.tile_id not in state.structure.tiles:
            return
        tile_type = state.structure.tiles[msg.tile_id].type_name
        if repair:
            self.repairs[msg.auction_id] = msg
            bid = compute_repair_bid(
                state.structure, self.team_model(), state.task(), msg.tile_id,
                self.standing_at or self.cache_of(tile_type), self.weight_supported, self.weight_distance,
            )
        else:
            bid = compute_bid(
                state.structure, self.team_model(), state.task(), msg.tile_id, self.cache_of(tile_type),
                self.weight_supported, self.weight_distance,
            )
        out = AuctionBid(
            auction_id=msg.auction_id, robot_name=self.robot_name, bid=bid.value, workload=bid.workload,
            supported_count=bid.supported_count, cache_distance=bid.cache_distance,
        )
        out.header.stamp = self.get_clock().now().to_msg()
        self.bid_pub.publish(out)
        self.bids_made[msg.auction_id] = out
        self.get_logger().info(
            f"bid {bid.value:.1f} for tile {msg.tile_id} (auction {msg.auction_id}): w={bid.workload:.1f} s, "
            f"c={bid.supported_count}, d={bid.cache_distance:.2f} m"
        )

    def on_award(self, msg: AuctionAward) -> None:
        state = self.executor_state
        if state is None or msg.winner != self.robot_name:
            return
        if msg.auction_id in self.acceptances:  # a copy: our acceptance may have been lost
            self.accept_pub.publish(self.acceptances[msg.auction_id])
            return
        received = time.time()
        repair = self.repairs.pop(msg.auction_id, None)
        if repair is not None:
            state.award_repair(msg.tile_id, list(repair.resting_on_it))
            index = 0
        else:
            index = state.award(msg.tile_id)
        latency = 0.0
        if not is_zero(msg.detection_wall_stamp):
            latency = received - stamp_to_seconds(msg.detection_wall_stamp)
        self.accept(msg, latency)
        what = (f"repairing it first: taking off {[*repair.resting_on_it, msg.tile_id]}" if repair is not None
                else f"placing it at position {index} of my task")
        self.get_logger().info(
            f"won tile {msg.tile_id} (auction {msg.auction_id}); {what}"
            + (f"; {latency * 1000:.1f} ms after detection" if latency else "")
        )
        self.step()

    def accept(self, award: AuctionAward, latency: float) -> None:
        ack = AuctionAcceptance(
            auction_id=award.auction_id, tile_id=award.tile_id, robot_name=self.robot_name, award_latency=latency
        )
        ack.header.stamp = self.get_clock().now().to_msg()
        self.accept_pub.publish(ack)
        self.acceptances[award.auction_id] = ack

    # --- acting -------------------------------------------------------------------------------
    def now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def step(self) -> None:
        state = self.executor_state
        if state is None:
            return
        if state.in_flight:
            self.watch_running_goal(state.in_flight)
            return
        if self.parking_since is not None:
            self.watch_drive_home()
            return
        if self.now() < self.retry_after:
            return
        held = self.contact.hold_reason(time.monotonic(), state.plan_revision)
        if held:
            self.get_logger().warn(f"starting no new tile: {held}", throttle_duration_sec=5.0)
            return
        decision = state.next_step()
        if decision.kind is StepKind.WAIT and decision.waiting_for != self.last_wait_logged:
            self.last_wait_logged = decision.waiting_for
            self.get_logger().info(f"tile {decision.tile_id} waits for supports {list(decision.waiting_for)}")
        if self.parking is not None and self.park(decision.kind is StepKind.DONE):
            return
        if decision.kind not in (StepKind.PLACE, StepKind.REMOVE):
            return
        if not self.driver_ready():
            if self.server_found_at is None:
                self.get_logger().warn(
                    "place_tile action server not available; is the robot driver running?", throttle_duration_sec=5.0
                )
            return
        if decision.kind is StepKind.REMOVE:
            if not self.remove_client.server_is_ready():
                self.get_logger().warn("remove_tile action server not available: the repair waits",
                                       throttle_duration_sec=5.0)
                return
            self.send_removal(decision.tile_id)
            return
        self.send_goal(decision.tile_id)

    def park(self, done: bool) -> bool:
        """Send the robot home when it has nothing left to place; whether a drive was sent."""
        assert self.parking is not None and self.executor_state is not None
        home = self.parking.drive_home(done, self.standing_at)
        if home is None or not self.navigate_client.server_is_ready():
            return False
        self.parking.started()
        tiles = self.executor_state.structure.tiles.values()
        centre = (sum(t.position[0] for t in tiles) / len(tiles), sum(t.position[1] for t in tiles) / len(tiles))
        goal = NavigateTo.Goal()
        goal.target.header.frame_id = self.executor_state.structure.frame_id
        goal.target.header.stamp = self.get_clock().now().to_msg()
        goal.target.pose.position.x, goal.target.pose.position.y = home
        heading = facing(home, centre)
        goal.target.pose.orientation.z, goal.target.pose.orientation.w = math.sin(heading / 2), math.cos(heading / 2)
        self.parking_since = time.monotonic()
        self.get_logger().info(f"nothing left to place: driving home to ({home[0]:.2f}, {home[1]:.2f})")
        self.navigate_client.send_goal_async(goal).add_done_callback(self.on_drive_home_response)
        return True

    def on_drive_home_response(self, future) -> None:  # type: ignore[no-untyped-def]
        handle = future.result()
        if handle is None or not handle.accepted:
            self.end_drive_home("the base refused the goal")
            return
        self.parking_handle = handle
        handle.get_result_async().add_done_callback(self.on_drive_home_result)

    def on_drive_home_result(self, future) -> None:  # type: ignore[no-untyped-def]
        response = future.result()
        ok = response.status == GoalStatus.STATUS_SUCCEEDED and response.result.success
        self.end_drive_home("" if ok else response.result.message or f"goal status {response.status}")

    def watch_drive_home(self) -> None:
        """A base that stops answering on the way home must not keep the robot from work."""
        assert self.parking_since is not None
        if self.navigate_client.server_is_ready():
            self.navigate_lost_since = None
        elif self.navigate_lost_since is None:
            self.navigate_lost_since = time.monotonic()
        lost = self.navigate_lost_since is not None and time.monotonic() - self.navigate_lost_since > 3.0
        if lost or time.monotonic() - self.parking_since > self.action_timeout:
            if self.parking_handle is not None:
                self.parking_handle.cancel_goal_async()
            self.end_drive_home("the base stopped answering" if lost else
                                f"no result within {self.action_timeout:.0f} s")

    def end_drive_home(self, failure: str) -> None:
        if self.parking_since is None:
            return
        self.parking_since, self.parking_handle, self.navigate_lost_since = None, None, None
        if failure:
            self.get_logger().warn(f"driving home failed ({failure}); waiting here")
        else:
            self.get_logger().info("home: waiting for work")
        self.step()

    def driver_ready(self) -> bool:
        """The robot's place_tile server has been reachable for `SERVER_SETTLE` s."""
        if not self.place_client.server_is_ready():
            self.server_found_at = None
            return False
        if self.server_found_at is None:
            self.server_found_at = time.monotonic()
        return time.monotonic() - self.server_found_at >= SERVER_SETTLE

    def watch_running_goal(self, tile_id: int) -> None:
        """A robot that stops answering must not hold its tile forever."""
        client = self.remove_client if self.executor_state and self.executor_state.removing else self.place_client
        if client.server_is_ready():
            self.server_lost_since = None
        elif self.server_lost_since is None:
            self.server_lost_since = time.monotonic()
        lost = self.server_lost_since is not None and time.monotonic() - self.server_lost_since > 3.0
        overdue = self.now() - self.goal_sent_at > self.action_timeout
        if not (lost or overdue):
            return
        if self.goal_handle is not None:
            self.goal_handle.cancel_goal_async()
        self.goal_handle = None
        self.server_lost_since = None
        why = "the robot stopped answering" if lost else f"no result within {self.action_timeout:.0f} s"
        if self.executor_state is not None and self.executor_state.removing:
            self.on_removal_done(tile_id, False, why, ())
        else:
            self.on_placement_done(tile_id, False, why, ())

    def send_goal(self, tile_id: int) -> None:
        state = self.executor_state
        assert state is not None
        tile = state.structure.tiles[tile_id]
        goal = PlaceTile.Goal(tile_id=tile_id, tile_type=tile.type_name)
        goal.pose = PoseStamped()
        goal.pose.header.frame_id = state.structure.frame_id
        goal.pose.header.stamp = self.get_clock().now().to_msg()
        goal.pose.pose = pose_of(tile)
        cache = self.cache_of(tile.type_name) or (0.0, 0.0)
        goal.cache = Point(x=cache[0], y=cache[1], z=0.0)
        state.start(tile_id)
        self.goal_sent_at = self.now()
        self.get_logger().info(f"placing tile {tile_id} ({tile.type_name}), attempt {state.attempts[tile_id]}")
        future = self.place_client.send_goal_async(goal, feedback_callback=self.on_feedback)
        future.add_done_callback(lambda f, t=tile_id: self.on_goal_response(t, f))

    def send_removal(self, tile_id: int) -> None:
        """Take `tile_id` off the structure (a repair), to this robot's cache of its type."""
        state = self.executor_state
        assert state is not None
        tile = state.structure.tiles[tile_id]
        goal = RemoveTile.Goal(tile_id=tile_id, tile_type=tile.type_name)
        goal.pose.header.frame_id = state.structure.frame_id
        goal.pose.header.stamp = self.get_clock().now().to_msg()
        goal.pose.pose = pose_of(tile)
        drop_off = self.cache_of(tile.type_name) or (0.0, 0.0)
        goal.drop_off = Point(x=drop_off[0], y=drop_off[1], z=0.0)
        state.start_removal(tile_id)
        self.goal_sent_at = self.now()
        self.get_logger().info(f"taking tile {tile_id} off the structure, attempt {state.removal_attempts[tile_id]}")
        future = self.remove_client.send_goal_async(goal, feedback_callback=self.on_feedback)
        future.add_done_callback(lambda f, t=tile_id: self.on_goal_response(t, f))

    def on_goal_response(self, tile_id: int, future) -> None:  # type: ignore[no-untyped-def]
        state = self.executor_state
        if state is None or state.in_flight != tile_id:
            return  # given up on already
        handle = future.result()
        if handle is None or not handle.accepted:
            done = self.on_removal_done if state.removing else self.on_placement_done
            done(tile_id, False, "the robot refused the goal", ())
            return
        self.goal_handle = handle
        handle.get_result_async().add_done_callback(lambda f, t=tile_id: self.on_result(t, f))

    def on_result(self, tile_id: int, future) -> None:  # type: ignore[no-untyped-def]
        state = self.executor_state
        if state is None or state.in_flight != tile_id:
            return  # given up on already
        self.goal_handle = None
        response = future.result()
        result = response.result
        reason = result.message or f"goal status {response.status}"
        if state.removing:
            ok = response.status == GoalStatus.STATUS_SUCCEEDED and result.error_code in (
                RemoveTile.Result.SUCCEEDED, RemoveTile.Result.ALREADY_ABSENT)
            self.on_removal_done(tile_id, ok, reason, tuple(result.resting_on_it))
            return
        ok = response.status == GoalStatus.STATUS_SUCCEEDED and result.error_code in (
            PlaceTile.Result.SUCCEEDED,
            PlaceTile.Result.ALREADY_PRESENT,
        )
        absent = tuple(result.missing_supports) if result.error_code == PlaceTile.Result.FAILED_PRECONDITION else ()
        wrong = tuple(result.wrong_tiles) if result.error_code == PlaceTile.Result.FAILED_BLOCKED else ()
        self.on_placement_done(tile_id, ok, reason, absent, wrong)

    def on_removal_done(self, tile_id: int, success: bool, reason: str, resting_on_it: tuple[int, ...]) -> None:
        state = self.executor_state
        assert state is not None
        attempts = state.removal_attempts.get(tile_id, 1)
        outcome = state.finish_removal(tile_id, success, resting_on_it)
        if outcome is Outcome.REMOVED:
            self.publish_report(tile_id, PlacementReport.OUTCOME_REMOVED, attempts, "taken off for a repair")
            self.get_logger().info(f"took tile {tile_id} off the structure")
        elif outcome is Outcome.RETRY:
            self.retry_after = self.now() + (0.0 if resting_on_it else self.retry_delay)
            self.get_logger().warn(f"taking tile {tile_id} off failed ({reason}); trying again")
        else:
            self.publish_report(tile_id, PlacementReport.OUTCOME_FAILED, attempts, f"repair given up: {reason}")
            self.get_logger().error(f"gave up the repair of tile {tile_id} after {attempts} attempts: {reason}")
        self.publish_status()
        self.step()

    def on_placement_done(
        self, tile_id: int, success: bool, reason: str, absent: tuple[int, ...], wrong: tuple[int, ...] = ()
    ) -> None:
        state = self.executor_state
        assert state is not None
        attempts = state.attempts.get(tile_id, 1)
        outcome = state.finish(tile_id, success, absent, wrong)
        if outcome is Outcome.WAITS_FOR_REPAIR:
            self.publish_report(tile_id, PlacementReport.OUTCOME_BLOCKED, attempts, reason, wrong_tiles=wrong)
            self.get_logger().warn(f"tile {tile_id} waits for the repair of {', '.join(map(str, wrong))} ({reason})")
        elif outcome is Outcome.PLACED:
            self.publish_report(tile_id, PlacementReport.OUTCOME_PLACED, attempts, "")
            self.get_logger().info(f"placed tile {tile_id}")
        elif outcome is Outcome.BLOCKED:
            self.publish_report(tile_id, PlacementReport.OUTCOME_SUPPORT_MISSING, attempts, reason, absent)
            self.get_logger().warn(
                f"tile {tile_id} waits: support {', '.join(map(str, absent))} is not there ({reason})"
            )
        elif outcome is Outcome.RETRY:
            self.retry_after = self.now() + self.retry_delay
            self.get_logger().warn(f"placing tile {tile_id} failed ({reason}); retrying in {self.retry_delay:.0f} s")
        else:
            self.publish_report(tile_id, PlacementReport.OUTCOME_FAILED, attempts, reason)
            self.get_logger().error(f"gave up tile {tile_id} after {attempts} attempts: {reason}")
        self.publish_status()
        self.step()

    def publish_report(
        self, tile_id: int, outcome: int, attempts: int, reason: str, absent: tuple[int, ...] = (),
        wrong_tiles: tuple[int, ...] = (),
    ) -> None:
        state = self.executor_state
        assert state is not None
        report = PlacementReport(
            robot_name=self.robot_name, tile_id=tile_id, outcome=outcome, attempts=attempts, reason=reason,
            missing_supports=list(absent), wrong_tiles=list(wrong_tiles),
        )
        report.header.stamp = self.get_clock().now().to_msg()
        report.header.frame_id = state.structure.frame_id
        report.pose = pose_of(state.structure.tiles[tile_id])
        self.report_pub.publish(report)

    def publish_status(self) -> None:
        status = RobotStatus(robot_name=self.robot_name)
        status.header.stamp = self.get_clock().now().to_msg()
        status.driver_ready = self.driver_ready()
        state = self.executor_state
        if state is None:
            status.state = RobotStatus.IDLE
        else:
            kind = state.next_step().kind
            status.state = {
                StepKind.IDLE: RobotStatus.IDLE,
                StepKind.WAIT: RobotStatus.WAITING,
                StepKind.BUSY: RobotStatus.PLACING,
                StepKind.PLACE: RobotStatus.WAITING,
                StepKind.REMOVE: RobotStatus.WAITING,
                StepKind.DONE: RobotStatus.DONE,
            }[kind]
            status.current_tile = state.in_flight
            status.plan_revision = max(state.plan_revision, 0)
            status.remaining_tiles = state.task()
            status.placed_tiles = list(state.placed_by_me)
            status.remaining_workload = self.team_model().workload(state.structure, state.task())
        self.status_pub.publish(status)


def main(args: list[str] | None = None) -> int:
    return run_node(AssemblyNode, (ValueError, StructureError), args=args, error_prefix="assembly_node")


if __name__ == "__main__":
    sys.exit(main())
