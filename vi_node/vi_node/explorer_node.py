"""vi_explorer: drives the VI robot from viewpoint to viewpoint (paper section 2.2, prioritized
exploration). Runs in the VI robot's namespace (`/vi`, or `/vi1`, `/vi2`, ... for several), next to
its `vi_node`.

A thin adapter around `exploration.Exploration` and `viewpoint.rank_viewpoints`. In: the latched
`/structure`, `/placement_reports` (tiles claimed placed, and supports a robot found absent: the
priority), `/robot_status` (the tiles each robot places now and next: their supports are the
currently targeted building region), `/auction/announcements` (tiles no longer expected),
`/tile_states` (what the scans of every VI robot judged). Out: goals to the base's `navigate_to`
action. After each arrival it waits for the first tile states of a scan its own robot took there
(`robot_name`; vi_node answers every scan: tile states, or why it has none), then chooses again.
While it stays, it chooses again on the states of its own robot's next scans. A goal chosen on a
scan's states is stamped with that scan's time: what it knew as of then (a simulated base sets off
at a time set by that stamp, not by when the goal reached it). With several VI robots, each claims
its next viewpoint (`viewpoint_claims`) and leaves the others' to them (`exploration`). The other
robots' overhead poses (`other_robots`, as vi_node follows them) tell it what they hide and where it
cannot stand: a robot parked beside the structure blinds every viewpoint behind it.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionClient
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from tiling_assembly.geometry import quaternion_from_rotation, rotation_from_rpy
from tiling_assembly.messages import structure_from_msg
from tiling_assembly.scan_freshness import RepeatFilter
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import NavigateTo
from tiling_assembly_msgs.msg import (
    AuctionAnnouncement,
    PlacementReport,
    RobotStatus,
    Structure,
    TileState,
    TileStateArray,
)
from tiling_ros.parameters import declare_settings, setting
from tiling_ros.qos import COORDINATION, HEARTBEATS, LATCHED, OTHER_ROBOT_POSES, REPORTS
from tiling_ros.spinning import run_node
from tiling_ros.stamps import is_zero, stamp_from_seconds, stamp_to_nanoseconds, stamp_to_seconds
from vi_node.camera_model import PinholeCamera
from vi_node.evidence import EvidenceSettings
from vi_node.exploration import (
    MISSING,
    OCCLUDED,
    PRESENT,
    UNKNOWN,
    Exploration,
    PriorityWeights,
    ring_viewpoints,
)
from vi_node.inspection_settings import InspectionSettings
from vi_node.other_robots import OtherRobots
from vi_node.pose_matching import TeamPoses
from vi_node.pose_prior import CameraMount, OverheadPose
from vi_node.raycast import VirtualScene
from vi_node.robot_mask import RobotBoxes
from vi_node.viewpoint import ViewpointScore, rank_viewpoints
from vi_node.viewpoint_claims import ViewpointClaims

# the camera and the evidence rules are vi_node's (the same names in config/vi_node.yaml)
_CAMERA = InspectionSettings()
_EVIDENCE = EvidenceSettings()
STATES = {TileState.PRESENT: PRESENT, TileState.MISSING: MISSING, TileState.OCCLUDED: OCCLUDED}
ROBOT_BOXES = _CAMERA.robot_mask()
ROBOT_POSE_AGE = 60.0  # s: a robot's latest overhead pose stands for it that long (robots wait long)
FIRST_GOAL_DISCOVERY = 3.0  # s of wall time for the other VI robots to be discovered before the first goal
FIRST_GOAL_PATIENCE = 10.0  # s of wall time after which the first goal goes without this robot's own pose
STATUS_CHANGES = 20  # the latest changes of what each assembly robot works on, kept for choices made as of a scan
STAMP_SLACK = 1e-6  # s: a frame taken at the arrival + settle may be stamped a nanosecond short of it


@dataclass(frozen=True)
class ExplorerSettings:
    """The parameters of vi_explorer (read from config/vi_node.yaml), with their defaults."""

    structure_file: str = setting("", "Structure used until /structure arrives.")
    camera_xyz: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        _CAMERA.camera_xyz, "camera_link in base_link: x, y, z (m).")
    camera_rpy: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        _CAMERA.camera_rpy, "camera_link in base_link: roll, pitch, yaw (rad).")
    intrinsics: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        _CAMERA.intrinsics, "Depth camera fx, fy, cx, cy (px).")
    intrinsics_size: list[int] = setting(  # noqa: RUF009 - a field() with a default_factory
        _CAMERA.intrinsics_size, "Image width, height the intrinsics are given for (px).")
    max_incidence: float = setting(_EVIDENCE.max_incidence, "Steepest judged view (rad).")
    min_observed_pixels: int = setting(_EVIDENCE.min_observed_pixels, "Judged pixels a tile needs to be resolved.")
    min_range: float = setting(_CAMERA.min_range, "Nearest depth measured (m).")
    max_range: float = setting(_CAMERA.max_range, "Farthest depth measured (m).")
    viewpoint_radii: list[float] = setting([0.9, 1.2], "Rings of viewpoints (m).")  # noqa: RUF009
    viewpoints_per_ring: int = setting(8, "Viewpoints on each ring.")
    settle_time: float = setting(0.2, "s after arriving before a scan counts.")
    scan_timeout: float = setting(
        5.0, "s to wait at a viewpoint for a scan's verdict, on the node's clock (simulated time in the simulation, "
        "which waits for a busy vi_node; vi_node answers every scan, with states or the reason there are none: "
        "this only covers a silent vi_node).")
    travel_cost: float = setting(0.5, "Priority points one metre of driving costs.")
    other_robots: str = setting(_CAMERA.other_robots, "Robots whose overhead_pose to follow, comma-separated "
                                "(empty: every one that appears).")
    claim_clearance: float = setting(
        Exploration.claim_clearance, "m: viewpoints this near one another VI robot claimed are left to it.")
    shared_weight: float = setting(
        Exploration.shared_weight, "Share of its priority a tile keeps that another VI robot's claimed view resolves.")
    claim_age: float = setting(120.0, "s a viewpoint another VI robot claimed stands without news of it.")
    idle_wait: float = setting(
        3.0, "s of simulated time the robot stays without stopping for a scan when no other viewpoint is better "
        "(the camera's own frames go on meanwhile; a tile that becomes unresolved ends the wait).")


class ExplorerNode(Node):
    def __init__(self) -> None:
        super().__init__("vi_explorer")

        settings = self.settings = declare_settings(self, ExplorerSettings)
        self.structure_file = str(settings.structure_file)
        self.evidence = EvidenceSettings(
            max_incidence=float(settings.max_incidence), min_observed_pixels=int(settings.min_observed_pixels)
        )
        self.range = (float(settings.min_range), float(settings.max_range))
        self.radii = [float(r) for r in settings.viewpoint_radii]
        self.per_ring = int(settings.viewpoints_per_ring)
        self.settle = float(settings.settle_time)
        self.scan_timeout = float(settings.scan_timeout)
        travel_cost = float(settings.travel_cost)
        if not self.radii or any(r <= 0 for r in self.radii) or self.per_ring < 1:
            raise ValueError("viewpoint_radii must be positive and viewpoints_per_ring at least 1")
        self.mount = CameraMount(tuple(settings.camera_xyz), tuple(settings.camera_rpy))  # type: ignore[arg-type]
        fx, fy, cx, cy = (float(v) for v in settings.intrinsics)
        size = settings.intrinsics_size
        self.camera = PinholeCamera(fx, fy, cx, cy, int(size[0]), int(size[1]))

        self.exploration = Exploration(PriorityWeights(), travel_cost=travel_cost,
                                       claim_clearance=float(settings.claim_clearance),
                                       shared_weight=float(settings.shared_weight))
        self.robot_name = self.get_namespace().strip("/")
        self.structure = None
        self.candidates: list[tuple[float, float, float]] = []
        self.placed: dict[int, int] = {}  # tile -> stamp (ns) of its latest placement report
        self.withdrawn: dict[int, int] = {}  # tile -> stamp (ns) of its latest announcement
        # assembly robot -> (stamp ns, the tiles it places now and next), its latest changes
        self.working_on: dict[str, list[tuple[int, tuple[int, ...]]]] = {}
        self.scene: VirtualScene | None = None  # S_a for ray tracing candidate views
        self.scene_tiles: tuple[int, ...] = ()
        self.earlier_scene: tuple[tuple[int, ...], VirtualScene] | None = None  # S_a as of an earlier time
        self.here: tuple[float, float, float] | None = None
        self.start: tuple[float, float, float] | None = None  # the overhead cameras' pose before the first goal
        self.started_wall = time.monotonic()
        self.arrived_at: float | None = None  # s (node clock); None while driving
        self.idle_until = -math.inf  # s (node clock): staying put, no better place to look from
        self.latest_scan = -math.inf  # s: the stamp of the latest states of this robot's own scans
        self.waiting_on: set[int] = set()  # the tiles unresolved when the stay began
        self.driving = False
        self.repeats = RepeatFilter()
        self.team = TeamPoses()
        self.other_robots = OtherRobots(self, str(settings.other_robots), self.team.add,
                                        lambda line: self.get_logger().warn(line, throttle_duration_sec=10.0))
        self.other_robots.follow()
        graph = Clock(clock_type=ClockType.STEADY_TIME)  # who is there: the middleware's graph, not the world
        self.create_timer(1.0, self.other_robots.follow, clock=graph)
        self.claims = ViewpointClaims(self, float(settings.claim_age))
        self.create_timer(1.0, self.claims.follow, clock=graph)

        self.navigate = ActionClient(self, NavigateTo, "navigate_to")
        self.create_subscription(Structure, "/structure", self.on_structure, LATCHED)
        self.create_subscription(PlacementReport, "/placement_reports", self.on_report, REPORTS)
        self.create_subscription(AuctionAnnouncement, "/auction/announcements", self.on_announcement, COORDINATION)
        self.create_subscription(TileStateArray, "/tile_states", self.on_states, COORDINATION)
        self.create_subscription(RobotStatus, "/robot_status", self.on_robot_status, HEARTBEATS)
        self.create_subscription(PoseStamped, "overhead_pose", self.on_own_pose, OTHER_ROBOT_POSES)
        self.create_timer(0.5, self.tick)
        # the first goal goes on wall time: a simulator holds its clock at the start until it does
        self.create_timer(0.5, self.tick_before_a_first_goal, clock=Clock(clock_type=ClockType.STEADY_TIME))
        if self.structure_file:
            self.set_structure(load_structure(self.structure_file))

    def now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def set_structure(self, structure) -> None:  # type: ignore[no-untyped-def]
        self.structure = structure
        self.candidates = ring_viewpoints(structure, self.radii, self.per_ring)
        self.update_expected()

    def expected(self, as_of: float = math.inf) -> list[int]:
        """The tiles S_a held at `as_of` (s) by the reports stamped until then (before any: all of them)."""
        if self.structure is None:
            return []
        until = math.inf if math.isinf(as_of) else round(as_of * 1e9)
        placed = {t: stamp for t, stamp in self.placed.items() if stamp <= until}
        if not placed:
            return self.structure.tile_ids
        withdrawn = {t: stamp for t, stamp in self.withdrawn.items() if stamp <= until}
        return sorted(t for t, stamp in placed.items() if withdrawn.get(t, -1) < stamp)

    def scene_of(self, tiles: tuple[int, ...]) -> VirtualScene:
        """S_a of `tiles` for ray tracing (the current one, or that of an earlier time)."""
        if tiles == self.scene_tiles and self.scene is not None:
            return self.scene
        if self.earlier_scene is None or self.earlier_scene[0] != tiles:
            assert self.structure is not None
            self.earlier_scene = (tiles, VirtualScene([self.structure.tiles[t] for t in tiles]))
        return self.earlier_scene[1]

    def supports_worked_on(self, as_of: float) -> set[int]:
        """The supports of what each robot placed now and next at `as_of` (s): the targeted region."""
        assert self.structure is not None
        until = round(as_of * 1e9)
        supports = self.structure.supports
        out: set[int] = set()
        for changes in self.working_on.values():
            working = next((tiles for stamp, tiles in reversed(changes) if stamp <= until), ())
            out.update(s for t in working for s in supports.get(t, ()))
        return out

    def update_expected(self) -> None:
        expected = self.expected()
        self.exploration.expect(expected)
        if self.structure is not None and tuple(expected) != self.scene_tiles:
            self.scene_tiles = tuple(expected)
            self.scene = VirtualScene([self.structure.tiles[t] for t in expected])

    def on_structure(self, msg: Structure) -> None:
        try:
            self.set_structure(structure_from_msg(msg, "/structure"))
        except StructureError as error:
            self.get_logger().error(f"ignoring /structure: {error}")

    def on_report(self, msg: PlacementReport) -> None:
        reported = stamp_to_seconds(msg.header.stamp)
        if msg.outcome == PlacementReport.OUTCOME_SUPPORT_MISSING:
            for support in msg.missing_supports:
                self.exploration.suspected(support, reported)
            absent = ", ".join(map(str, msg.missing_supports))
            self.get_logger().info(f"{msg.robot_name} found tile(s) {absent} absent: looking there first")
            return
        if msg.outcome != PlacementReport.OUTCOME_PLACED:
            return
        self.placed[msg.tile_id] = stamp_to_nanoseconds(msg.header.stamp)
        self.update_expected()
        self.exploration.placed(msg.tile_id, reported)

    def on_announcement(self, msg: AuctionAnnouncement) -> None:
        self.withdrawn[msg.tile_id] = stamp_to_nanoseconds(msg.header.stamp)
        self.update_expected()

    def on_robot_status(self, msg: RobotStatus) -> None:
        """Where the building happens: what each robot places now and next, from when (its heartbeats
        repeat it; a change is stamped when it happened)."""
        busy = msg.state in (RobotStatus.WAITING, RobotStatus.PLACING)
        working = tuple(msg.remaining_tiles[:2]) if busy else ()
        changes = self.working_on.setdefault(msg.robot_name, [])
        if changes and changes[-1][1] == working:
            return
        changes.append((stamp_to_nanoseconds(msg.header.stamp), working))
        del changes[:-STATUS_CHANGES]

    def on_own_pose(self, msg: PoseStamped) -> None:
        """Where the robot stands before its first goal (VI robots start apart: each looks near itself)."""
        p, q = msg.pose.position, msg.pose.orientation
        try:
            pose = OverheadPose.from_quaternion(p.x, p.y, q.x, q.y, q.z, q.w)
        except ValueError:
            return  # a zero quaternion; vi_node says so
        self.start = (pose.x, pose.y, pose.yaw)

    def on_states(self, msg: TileStateArray) -> None:
        stamp = stamp_to_seconds(msg.header.stamp)
        seen = self.repeats.fresh_states(msg.states, msg.robot_name)
        view = None if msg.problem else (msg.camera_pose.position.x, msg.camera_pose.position.y)
        self.exploration.judged({s.tile_id: STATES.get(s.state, UNKNOWN) for s in msg.states if s.tile_id in seen},
                                stamp, view)
        if msg.robot_name and msg.robot_name != self.robot_name:
            return  # another VI robot's scan: what it saw counts, but this robot's wait goes on
        self.latest_scan = max(self.latest_scan, stamp)
        if self.arrived_at is not None and stamp >= self.arrived_at + self.settle - STAMP_SLACK:
            if msg.problem and self.here is not None:  # the scan taken here gave no states
                self.get_logger().info(f"no tile states from this viewpoint ({msg.problem}); trying another")
                self.exploration.viewpoint_failed(self.candidates.index(self.here), stamp)
            self.arrived_at = None  # this viewpoint is done
            self.tick(decided_on=stamp)
        elif self.arrived_at is None and not self.driving and not self.staying(stamp):
            self.tick(decided_on=stamp)  # a scan streamed while it stays: time to choose again

    def staying(self, at: float) -> bool:
        """Whether the robot goes on staying where it stands at `at` (s): its stay lasts and no tile
        became unresolved since it began."""
        return at < self.idle_until and set(self.exploration.unresolved(at, self.expected(at))) <= self.waiting_on

    def scans_stream(self, now: float) -> bool:
        """Whether this robot's own scans' states keep coming while it stays: then it chooses on them
        (at their time), not on its timer (at whatever time the clock shows when the host lets it)."""
        return now - max(self.latest_scan, self.idle_until) < 2 * self.scan_timeout

    def tick(self, decided_on: float | None = None) -> None:
        """Choose the next viewpoint; `decided_on`: the stamp (s) of this robot's scan whose states
        prompt the choice (None: the timer's, at the clock's time)."""
        if self.structure is None or self.driving or self.scene is None or not self.scene_tiles:
            return
        if self.here is None and not self.ready_for_a_first_goal():
            return
        now = self.now() if decided_on is None else decided_on
        if decided_on is None and self.arrived_at is None and self.here is not None and self.scans_stream(now):
            return  # staying: the next scan's states prompt the next choice
        if self.arrived_at is not None and now < self.arrived_at + self.scan_timeout:
            return  # still waiting for the verdict of a scan from here
        if self.arrived_at is not None:
            self.get_logger().warn(f"no verdict on a scan from this viewpoint within {self.scan_timeout:g} s; "
                                   "trying another")
            if self.here is not None:
                self.exploration.viewpoint_failed(self.candidates.index(self.here), now)
            self.arrived_at = None
        if self.staying(now):
            return
        if not self.navigate.server_is_ready():
            self.get_logger().warn("navigate_to is not available", throttle_duration_sec=10.0)
            return
        expected = self.expected(now)
        if not expected:
            return  # nothing stood at that time: nothing to look at
        index, score = self.choose(now, expected)
        if self.candidates[index] == self.here:
            # the camera's frames go on while it stands; stopping for another look from here would take
            # a frame every settle time (0.2 s), sooner than a robot's vi_node judges one
            self.idle_until = now + float(self.settings.idle_wait)
            self.waiting_on = set(self.exploration.unresolved(now, expected))
            return
        self.go_to(self.candidates[index], score, now, self.exploration.unresolved(now, expected))

    def choose(self, now: float, expected: list[int]) -> tuple[int, float]:
        """The best next viewpoint (index into the candidates) and its score, as known at `now` (s)."""
        assert self.structure is not None
        here = self.here or self.start or self.candidates[0]
        scene = self.scene_of(tuple(expected))
        tiles = [self.structure.tiles[t] for t in expected]
        low = np.min([t.aabb[0] for t in tiles], axis=0)
        high = np.max([t.aabb[1] for t in tiles], axis=0)
        poses = [OverheadPose(*c) for c in self.candidates]
        robots = self.team.at(round(now * 1e9), int(ROBOT_POSE_AGE * 1e9))  # where they stood then
        blocking = RobotBoxes(robots, ROBOT_BOXES) if robots else None
        claimed = self.claims.current(now)
        self.exploration.targeted(self.supports_worked_on(now))

        def rank(at: list[OverheadPose], wanted: dict[int, float], robots: RobotBoxes | None) -> list[ViewpointScore]:
            return rank_viewpoints(scene, low, high, self.camera, self.mount, at, wanted, self.evidence,
                                   min_range=self.range[0], max_range=self.range[1], robots=robots)

        # the claimer stands at its claim soon: only the structure hides its view there
        theirs = rank([OverheadPose(*c) for c in claimed], self.exploration.priority(now, among=expected),
                      None) if claimed else []
        priority = self.exploration.priority(now, left_to_others={t for r in theirs for t in r.resolves},
                                             among=expected)
        ranked = rank(poses, priority, blocking)
        gain_of = {(r.pose.x, r.pose.y, r.pose.yaw): self.exploration.gain((r.pose.x, r.pose.y, r.pose.yaw),
                                                                            r.resolves, priority, now)
                   for r in ranked}
        gains = [gain_of[(p.x, p.y, p.yaw)] for p in poses]
        neighbours = [(p.x, p.y, p.yaw) for p in self.team.latest(self.claims.robots())]
        return self.exploration.choose(self.candidates, here, now, gains, claimed=claimed, neighbours=neighbours)

    def tick_before_a_first_goal(self) -> None:
        if self.here is None and not self.driving:
            self.tick()

    def ready_for_a_first_goal(self) -> bool:
        """The first viewpoint is chosen once this robot knows where it stands and the other VI robots
        have had `FIRST_GOAL_DISCOVERY` s to be found (they all choose at the start: each should see
        the others' side of the ring as theirs), or after `FIRST_GOAL_PATIENCE` s in any case."""
        waited = time.monotonic() - self.started_wall
        self.claims.follow()
        self.other_robots.follow()
        return (self.start is not None and waited >= FIRST_GOAL_DISCOVERY) or waited >= FIRST_GOAL_PATIENCE

    def go_to(self, pose: tuple[float, float, float], score: float, decided_at: float,
              unresolved: list[int]) -> None:
        goal = NavigateTo.Goal()
        goal.target = PoseStamped()
        goal.target.header.frame_id = "map"
        goal.target.header.stamp = stamp_from_seconds(decided_at)
        goal.target.pose.position.x, goal.target.pose.position.y = pose[0], pose[1]
        q = quaternion_from_rotation(rotation_from_rpy(0.0, 0.0, pose[2]))
        o = goal.target.pose.orientation
        o.x, o.y, o.z, o.w = q
        self.driving = True
        self.claims.claim(pose, decided_at)
        self.get_logger().info(
            f"next viewpoint ({pose[0]:+.2f}, {pose[1]:+.2f}, {math.degrees(pose[2]):+.0f} deg), score {score:.1f}, "
            f"chosen as of t={decided_at:.3f} s; unresolved tiles {unresolved}"
        )
        self.navigate.send_goal_async(goal).add_done_callback(lambda f: self.on_goal(f, pose))

    def on_goal(self, future, pose) -> None:  # type: ignore[no-untyped-def]
        handle = future.result()
        if handle is None or not handle.accepted:
            self.driving = False
            self.get_logger().warn("navigate_to refused the goal")
            return
        handle.get_result_async().add_done_callback(lambda f: self.on_arrival(f, pose))

    def on_arrival(self, future, pose) -> None:  # type: ignore[no-untyped-def]
        self.driving = False
        result = future.result().result
        if not result.success:
            self.get_logger().warn(f"could not reach the viewpoint: {result.message}")
            return
        self.here = pose
        # the base's own time of arrival: this node may hear of it late, and scans count from then
        arrival = result.final_pose.header.stamp
        self.arrived_at = self.now() if is_zero(arrival) else stamp_to_seconds(arrival)


def main(args: list[str] | None = None) -> int:
    return run_node(ExplorerNode, (ValueError, StructureError), args=args, error_prefix="vi_explorer")


if __name__ == "__main__":
    sys.exit(main())
