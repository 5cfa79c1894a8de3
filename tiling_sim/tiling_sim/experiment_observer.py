"""The experiment runner's eyes: a node that records one trial into a TrialRecord.

It listens to everything the team says (plans, placement reports, tile states, auctions, robot
status) and to the simulated world's events, releases the simulated clock once every node of the
trial is up, and tells the runner when the structure is complete.
"""

from __future__ import annotations

import json

from rclpy.context import Context
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import ReliabilityPolicy
from std_msgs.msg import Empty, String

from tiling_assembly.scan_freshness import RepeatFilter
from tiling_assembly_msgs.msg import (
    AssemblyPlan,
    AuctionAcceptance,
    AuctionAnnouncement,
    AuctionAward,
    AuctionBid,
    RobotStatus,
    TileState,
    TileStateArray,
)
from tiling_ros.qos import COORDINATION, DECISIONS, LATCHED, SIM_EVENTS
from tiling_ros.stamps import stamp_to_seconds
from tiling_sim.trial_record import (
    MISPLACED,
    MISSING,
    OCCLUDED,
    PRESENT,
    Announcement,
    AwardRecord,
    PlanRecord,
    RoomWait,
    Scan,
    StatusSample,
    TrialRecord,
    Verdict,
    WorldEvent,
)

STATE_NAMES = {TileState.PRESENT: PRESENT, TileState.MISSING: MISSING, TileState.OCCLUDED: OCCLUDED,
               TileState.MISPLACED: MISPLACED}


class ExperimentObserver(Node):
    def __init__(self, record: TrialRecord, robots: list[str], context: Context | None = None) -> None:
        super().__init__(f"experiment_observer_{record.trial}", context=context,
                         parameter_overrides=[Parameter("use_sim_time", value=True)])
        self.record = record
        self.robots = robots
        self.heard_from: set[str] = set()
        self.world_started = False
        self.start_sent = False
        self.complete = False
        self.repeats = RepeatFilter()  # fused states repeat what earlier scans of each VI robot saw
        self.heard_once: set[tuple[str, int, str]] = set()  # (topic, auction id, robot)
        self.start_pub = self.create_publisher(Empty, "/sim/start", SIM_EVENTS)
        self.create_subscription(String, "/sim/events", self.on_event, SIM_EVENTS)
        self.create_subscription(AssemblyPlan, "/plan", self.on_plan, LATCHED)
        self.create_subscription(TileStateArray, "/tile_states", self.on_states, COORDINATION)
        self.create_subscription(AuctionAnnouncement, "/auction/announcements", self.on_announcement, COORDINATION)
        self.create_subscription(AuctionAward, "/auction/awards", self.on_award, COORDINATION)
        self.create_subscription(AuctionAcceptance, "/auction/acceptances", self.on_acceptance, COORDINATION)
        self.create_subscription(AuctionBid, "/auction/bids", self.on_bid, COORDINATION)
        self.create_subscription(String, "/auction/decisions", self.on_decision, DECISIONS)
        self.create_subscription(RobotStatus, "/robot_status", self.on_status, COORDINATION)

    def now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    # --- start --------------------------------------------------------------------------------
    def ready_to_start(self, expected_nodes: list[str], sensor_readers: list[tuple[str, str]] = ()) -> list[str]:
        """What the trial still waits for before simulated time may run (empty: ready);
        `sensor_readers`: (topic, node) pairs, see `unread_sensors`."""
        names = {f"{ns.rstrip('/')}/{name}" for name, ns in self.get_node_names_and_namespaces()}
        waiting = [n for n in expected_nodes if n not in names]
        waiting += self.unread_sensors(sensor_readers)
        if not self.world_started:
            waiting.append("the world's first event")
        if not self.record.plans:
            waiting.append("the plan")
        # a robot that cannot reach its place_tile server yet, or has not taken up its task (the plan
        # reaches robots at different moments), would start late on simulated time
        waiting += [f"{r}'s heartbeat with its driver ready and its task taken up" for r in self.robots
                    if r not in self.heard_from]
        return waiting

    def unread_sensors(self, sensor_readers: list[tuple[str, str]]) -> list[str]:
        """The (topic, node) pairs where the node does not read the topic yet as its publishers offer
        it. A node is listed before its constructor has subscribed, and a best-effort reader of a
        reliable cloud loses it (Fast DDS drops fragmented samples there) until vi_node's `auto`
        switches: a scan taken meanwhile is lost, and the VI robot's path, and every detection after
        it, would depend on how fast the host started the processes."""
        waiting = []
        for topic, node in sensor_readers:
            publishers = self.get_publishers_info_by_topic(topic)
            readers = [i for i in self.get_subscriptions_info_by_topic(topic)
                       if f"{i.node_namespace.rstrip('/')}/{i.node_name}" == node]
            reliable = bool(publishers) and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                                                for i in publishers)
            if not publishers or not readers or (
                    reliable and all(i.qos_profile.reliability != ReliabilityPolicy.RELIABLE for i in readers)):
                waiting.append(f"{node} reading {topic}" + (" reliably, as it is offered" if reliable else ""))
        return waiting

    def start(self) -> None:
        if not self.start_sent:
            self.start_pub.publish(Empty())
            self.start_sent = True

    # --- recording ----------------------------------------------------------------------------
    def on_event(self, msg: String) -> None:
        data = json.loads(msg.data)
        kind = data["event"]
        if kind == "started":
            self.world_started = True
            return
        if kind == "scan_judged":
            self.record.verdicts.append(
                Verdict(float(data["t"]), float(data["wall_delay"]), str(data.get("problem", "")),
                        str(data.get("robot", "")))
            )
            return
        if kind == "scan_unjudged":
            self.record.unjudged_scans.append(float(data["scan_t"]))
            return
        if kind == "room_wait":
            self.record.room_waits.append(RoomWait(str(data["robot"]), float(data["since"]), float(data["seconds"]),
                                                   tuple(data.get("in_the_way", ())), bool(data.get("forced")),
                                                   bool(data.get("elsewhere"))))
            return
        event = WorldEvent(t=float(data["t"]), kind=kind, tile=int(data.get("tile", 0)),
                           robot=str(data.get("robot", "")), reason=str(data.get("reason", "")),
                           misplacement=str(data.get("misplacement", "")))
        self.record.events.append(event)
        if kind == "complete" and int(data.get("pending_removals", 0)) == 0:
            self.record.completed_at = event.t
            self.complete = True
        elif kind == "removed":
            self.complete = False
            self.record.completed_at = None

    def on_plan(self, msg: AssemblyPlan) -> None:
        self.record.plans.append(PlanRecord(
            t=self.now(), revision=msg.revision, method=msg.method,
            tasks={t.robot_name: list(t.tile_ids) for t in msg.tasks},
            makespan=msg.makespan, lower_bound=msg.lower_bound,
            finishes={t.robot_name: t.estimated_finish for t in msg.tasks},
        ))

    def on_states(self, msg: TileStateArray) -> None:
        if msg.problem:
            return  # a scan with no states: the world's verdict event records it
        states = {s.tile_id: STATE_NAMES.get(s.state, "unknown") for s in msg.states}
        # fused states repeat what earlier scans saw: a tile's counts change when this scan saw it
        fresh = frozenset(self.repeats.fresh_states(msg.states, msg.robot_name))
        self.record.scans.append(Scan(t=stamp_to_seconds(msg.header.stamp), states=states, fresh=fresh))
        self.record.final_states.update(states)

    def first_time(self, topic: str, auction_id: int, robot: str = "") -> bool:
        """False for a copy (the auction repeats unanswered messages over a lossy link)."""
        key = (topic, auction_id, robot)
        if key in self.heard_once:
            self.record.copies[topic] = self.record.copies.get(topic, 0) + 1
            return False
        self.heard_once.add(key)
        return True

    def on_announcement(self, msg: AuctionAnnouncement) -> None:
        if not self.first_time("announcements", msg.auction_id):
            return
        self.record.announcements.append(
            Announcement(stamp_to_seconds(msg.header.stamp), msg.auction_id, msg.tile_id, msg.reason))

    def on_award(self, msg: AuctionAward) -> None:
        if not self.first_time("awards", msg.auction_id):
            return
        self.record.awards.append(
            AwardRecord(stamp_to_seconds(msg.header.stamp), msg.auction_id, msg.tile_id, msg.winner, msg.decision))

    def on_bid(self, msg: AuctionBid) -> None:
        self.first_time("bids", msg.auction_id, msg.robot_name)

    def on_acceptance(self, msg: AuctionAcceptance) -> None:
        if self.first_time("acceptances", msg.auction_id) and msg.award_latency > 0:
            self.record.award_latencies.append(msg.award_latency)

    def on_decision(self, msg: String) -> None:
        self.record.decisions.append(msg.data)

    def on_status(self, msg: RobotStatus) -> None:
        if msg.driver_ready and msg.state != RobotStatus.IDLE:
            self.heard_from.add(msg.robot_name)
        if self.start_sent:
            self.record.statuses.append(
                StatusSample(stamp_to_seconds(msg.header.stamp), msg.robot_name, msg.state, msg.current_tile))
