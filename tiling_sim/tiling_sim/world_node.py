"""sim_world: the simulated testbed's world, the default when no robot is attached (paper section 3).

What no robot carries on board, in one process (the world host under `--hosts netns`): the
simulated `/clock` (running `real_time_factor` times faster than the wall clock, paced by the VI
robots' scans, see `sim_clock` and `scan_hold`, and held at the end of an assembly robot's phase until
its body goes on, see `body_hold`, and at each removal's time), the physical structure S_p, the faults (tiles
removed at random times, tiles slipping from a gripper, landing shifted, turned or of the wrong
type, and the repairs that take them off again), the overhead localization of every robot
(`/<robot>/overhead_pose`, true pose plus the paper's errors of up to 5 cm and 10 degrees) and
`/sim/events` (JSON lines for the experiment runner; `/sim/start` starts the clock).

The robots' bodies are processes of their own, on their robots' hosts: `sim_robot` serves an
assembly robot's `place_tile`, `sim_vi` a VI robot's `navigate_to` and its Kinect. They meet the
world through the small simulator-internal interface of `sim_interface` (`/sim/place`,
`/sim/snapshot`, `/sim/motion`, `/sim/scan_progress`). All callbacks run on one thread, so a
snapshot, a placement step and a clock tick never interleave: a scan carries the time of the world
it shows, and events leave in the order they happened.
"""

from __future__ import annotations

import json
import math
import sys
import time
from typing import Any

import numpy as np
from geometry_msgs.msg import Point, PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import Empty, String

from tiling_assembly.geometry import quaternion_from_rotation
from tiling_assembly.messages import pose_of
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import SimMotion, SimScanProgress
from tiling_assembly_msgs.srv import SimPlace, SimSnapshot
from tiling_ros.parameters import declare_settings
from tiling_ros.qos import CLOCK, SIM_EVENTS, SIM_MOTION, SIM_SCAN_PROGRESS
from tiling_ros.spinning import run_node
from tiling_ros.stamps import stamp_from_seconds, stamp_to_nanoseconds
from tiling_sim import sim_interface as sim
from tiling_sim.body_hold import TEAM, BodyHold
from tiling_sim.clock_ledger import ClockLedger, Holder
from tiling_sim.faults import FaultInjector, choose_wrong_tiles
from tiling_sim.overhead_cameras import OverheadCameras, Pose2
from tiling_sim.scan_hold import ScanHold
from tiling_sim.sim_clock import Pace, SimClock
from tiling_sim.sim_settings import WorldSettings
from tiling_sim.standing_room import StandingRoom
from tiling_sim.whereabouts import Whereabouts
from tiling_sim.world import PhysicalWorld
from tiling_sim.world_referee import StepAnswer, WorldReferee

OUTCOME_CODES = {
    "ok": SimPlace.Response.OK, "already present": SimPlace.Response.ALREADY_PRESENT,
    "support missing": SimPlace.Response.SUPPORT_MISSING, "unknown tile": SimPlace.Response.UNKNOWN_TILE,
    "dropped": SimPlace.Response.DROPPED, "blocked by a wrong tile": SimPlace.Response.BLOCKED,
    "not there": SimPlace.Response.NOT_THERE, "tile on top": SimPlace.Response.TILE_ON_TOP,
}


class SimWorld(Node):
    def __init__(self) -> None:
        super().__init__("sim_world")
        self.settings: WorldSettings = declare_settings(
            self, WorldSettings, dynamic_typing=True, build=WorldSettings.from_values
        )
        s = self.settings
        structure = load_structure(s.structure_file)
        faults = FaultInjector.scheduled(s.seed, s.removals, (s.removal_window_start, s.removal_window_end),
                                         s.drop_probability)
        faults.misplaced_tiles, faults.wrong_type_tiles = choose_wrong_tiles(
            s.seed, structure, s.misplacements, s.wrong_tiles)
        self.referee = WorldReferee(PhysicalWorld(structure), faults)
        self.robots = s.team
        starts: dict[str, Pose2] = {r: (x, y, 0.0) for r, (x, y) in s.robot_starts(structure).items()}
        self.vi_robots = s.vi_team
        self.whereabouts = Whereabouts({**starts, **s.vi_starts(structure)})
        self.room = StandingRoom(((s.robot_size[0] + s.robot_clearance) / 2, (s.robot_size[1] + s.robot_clearance) / 2),
                                 {robot: pose[:2] for robot, pose in self.whereabouts.poses.items()})
        self.cameras = OverheadCameras(s.seed, s.overhead_position_error, math.radians(s.overhead_yaw_error_deg),
                                       [*self.robots, *self.vi_robots])
        self.clock = SimClock(s.real_time_factor)
        self.hold = ScanHold(s.scan_hold_limit)
        self.body_hold = BodyHold(s.body_hold_limit)
        self.ledger = ClockLedger(s.clock_report_period)
        self.last_tick = time.monotonic()

        self.clock_pub = self.create_publisher(ClockMsg, "/clock", CLOCK)
        self.event_pub = self.create_publisher(String, sim.EVENTS, SIM_EVENTS)
        self.overhead_pubs = {name: self.create_publisher(PoseStamped, f"/{name}/overhead_pose", 10)
                              for name in self.whereabouts.poses}
        self.create_service(SimPlace, sim.PLACE, self.on_place)
        self.create_service(SimSnapshot, sim.SNAPSHOT, self.on_snapshot)
        self.create_subscription(SimMotion, sim.MOTION, self.on_motion, SIM_MOTION)
        self.create_subscription(SimScanProgress, sim.SCAN_PROGRESS, self.on_scan_progress, SIM_SCAN_PROGRESS)
        self.create_subscription(Empty, sim.START, self.on_start, SIM_EVENTS)
        self.create_timer(s.clock_step, self.tick, clock=Clock(clock_type=ClockType.STEADY_TIME))
        if not s.wait_for_start:
            self.start_clock()
        self.event("started", robots=self.robots, structure=structure.name,
                   removal_times=[round(t, 1) for t in faults.removal_times],
                   misplaced_tiles=sorted(faults.misplaced_tiles), wrong_type_tiles=sorted(faults.wrong_type_tiles))
        self.get_logger().info(
            f"simulating {structure.name} with {', '.join(self.robots)} and {', '.join(self.vi_robots)} at "
            f"{s.real_time_factor:g}x real time; {len(faults.removal_times)} removals, {s.misplacements} "
            f"misplacements and {s.wrong_tiles} wrong tiles scheduled"
        )

    # --- simulated time -----------------------------------------------------------------------
    def now(self) -> float:
        """Simulated time up to this moment, at the pace it has run since the last tick."""
        removal = self.referee.faults.next_removal_after(self.clock.now)
        ceilings = [c for c in (self.body_hold.ceiling(), self.hold.ceiling(), removal) if c is not None]
        wall = time.monotonic()
        return self.clock.advance(wall, self.hold.pace(wall), ceiling=min(ceilings, default=None))

    def on_start(self, _msg: Empty) -> None:
        if not self.clock.running:
            self.start_clock()
            self.get_logger().info("start: simulated time runs")

    def start_clock(self) -> None:
        self.clock.start(time.monotonic())
        self.body_hold.starting(self.robots, self.clock.now, self.settings.start_window)
        self.hold.starting(self.vi_robots, time.monotonic(), self.settings.vi_start_window)
        # the overhead cameras see every robot where it starts: an explorer chooses its first viewpoint from
        # there (without, it waited 10 s of wall time for a frame that the held clock never let come)
        stamp = stamp_from_seconds(self.clock.now)
        for name, publisher in self.overhead_pubs.items():
            publisher.publish(self.overhead_pose(name, stamp))

    def tick(self) -> None:
        wall = time.monotonic()
        if self.clock.running and self.settings.clock_report_period > 0:
            self.ledger.charge(wall, wall - self.last_tick, self.holders(wall), self.clock.now)
            if self.ledger.due(wall):
                self.get_logger().info(self.ledger.report(wall, self.clock.now))
        self.last_tick = wall
        for robot in self.hold.lapsed(wall, self.clock.now):
            self.get_logger().warn(f"{robot}'s scan held the clock for over {self.settings.scan_hold_limit:g} s "
                                   "of wall time: running on without it")
        lapsed = self.body_hold.lapsed(self.clock.now, wall) if self.clock.running else []
        for robot in lapsed:
            self.get_logger().warn(f"{robot}'s body held the clock for over {self.settings.body_hold_limit:g} s of "
                                   "wall time at the end of a phase: running on without it")
        now = self.now()
        self.arrive(now)  # before anything a body could do at this time
        self.clock_pub.publish(ClockMsg(clock=stamp_from_seconds(now)))
        removal = self.referee.remove_due(now)
        if removal is not None:
            self.get_logger().info(f"fault: tile {removal[1]['tile']} removed from the structure")
            self.publish_events([removal])

    def holders(self, wall: float) -> list[Holder]:
        """Who holds the clock at `wall` (s): the VI robots stopping it, else those at whose ceiling it stands."""
        if self.hold.pace(wall) is Pace.STOPPED:
            return [Holder("scan", robot) for robot in self.hold.stopping(wall)] or [Holder("scan")]
        now = self.clock.now
        deciding = self.body_hold.deciding(now)
        held = [Holder("reaction") if robot == TEAM else Holder("step", robot) for robot in deciding]
        return held + [Holder("frame", robot) for robot in self.hold.at_ceiling(now)]

    def arrive(self, now: float) -> None:
        for robot in self.whereabouts.arrive(now):
            self.cameras.stopped(robot)

    def event(self, kind: str, **fields: Any) -> None:
        self.event_pub.publish(String(data=json.dumps({"t": round(self.clock.now, 3), "event": kind, **fields})))

    def publish_events(self, events: list[tuple[str, dict[str, Any]]]) -> None:
        for kind, fields in events:
            self.event(kind, **fields)

    # --- the bodies ---------------------------------------------------------------------------
    def on_motion(self, msg: SimMotion) -> None:
        if not self.whereabouts.knows(msg.robot):
            self.get_logger().warn(f"/sim/motion from unknown robot '{msg.robot}': ignored",
                                   throttle_duration_sec=10.0)
            return
        self.whereabouts.expect(msg.robot, msg.arrive_at, (msg.x, msg.y, msg.yaw))
        if msg.robot in self.vi_robots:
            self.room.moved(msg.robot, (msg.x, msg.y))
            self.hold.moved(msg.robot, until=msg.arrive_at + sim.VI_SETTLE if msg.busy else None)
        if msg.robot in self.robots:
            self.now()  # the time up to this news ran under the old ceiling
            if msg.busy:
                self.body_hold.busy_until(msg.robot, msg.arrive_at)
                if msg.arrive_at <= self.clock.now + 1e-9:  # its goal ended now: what it did, others react to
                    self.body_hold.reacting(msg.arrive_at, self.settings.reaction_window)
            else:
                self.body_hold.idle(msg.robot)
        self.arrive(self.now())  # a phase that ends at once (or a late message) takes effect now

    def on_place(self, request: SimPlace.Request, response: SimPlace.Response) -> SimPlace.Response:
        now = self.now()  # the events carry the time the step reached the world
        response.stamp = stamp_from_seconds(now)
        steps = {SimPlace.Request.STARTING: self.referee.starting, SimPlace.Request.PICKED: self.referee.picked,
                 SimPlace.Request.PLACING: self.referee.placing, SimPlace.Request.REMOVING: self.referee.removing,
                 SimPlace.Request.LIFTED: self.referee.lifted}
        if request.step == SimPlace.Request.GOING_TO and request.robot in self.robots:
            return self.going_to(request, response, now)
        step = steps.get(request.step)
        if step is None or request.robot not in self.robots:
            response.outcome = SimPlace.Response.UNKNOWN_TILE
            response.reason = f"/sim/place: no step {request.step} for robot '{request.robot}'"
            return response
        if request.step in (SimPlace.Request.STARTING, SimPlace.Request.REMOVING):  # its phases count from here
            self.body_hold.busy_until(request.robot, now)
        answer: StepAnswer = step(request.robot, int(request.tile_id))
        self.publish_events(answer.events)
        response.outcome = OUTCOME_CODES[answer.outcome.value]
        response.reason = answer.reason
        response.absent_supports = answer.absent_supports
        response.wrong_tiles = answer.wrong_tiles
        response.resting_on_it = answer.resting_on_it
        return response

    def going_to(self, request: SimPlace.Request, response: SimPlace.Response, now: float) -> SimPlace.Response:
        """May the robot's base stand at (x, y)? Not where another robot stands or is going (`standing_room`);
        robots asking at the same time are answered in the team's order."""
        ahead = self.room.ahead(request.robot, now, self.robots, self.body_hold.deciding(now))
        if ahead:
            response.outcome = SimPlace.Response.ASK_AGAIN
            response.reason = f"{', '.join(ahead)} may still ask for room at this time, before {request.robot}"
            return response
        in_the_way, wait = self.room.ask(request.robot, (request.x, request.y), now, request.insist)
        if in_the_way:
            response.outcome = SimPlace.Response.ROBOT_IN_THE_WAY
            response.reason = f"{', '.join(in_the_way)} stands where {request.robot} would"
            response.robots = [Point(x=x, y=y, z=0.0) for x, y in self.room.others(request.robot)]
            return response
        if wait is not None:
            self.event("room_wait", robot=wait.robot, since=round(wait.since, 3), seconds=round(wait.seconds, 3),
                       in_the_way=list(wait.in_the_way), forced=wait.forced, elsewhere=wait.elsewhere)
        response.outcome = SimPlace.Response.OK
        return response

    def on_snapshot(self, request: SimSnapshot.Request, response: SimSnapshot.Response) -> SimSnapshot.Response:
        now = self.now()
        self.arrive(now)
        stamp = stamp_from_seconds(now)
        asking = request.robot or self.vi_robots[0]
        if request.hold_clock or request.hold_for > 0:
            self.hold.hold(stamp_to_nanoseconds(stamp), time.monotonic(), asking, stop=request.hold_clock,
                           period=request.hold_for, decision_window=request.decision_window)
        response.stamp = stamp
        world = self.referee.world
        response.present_tiles = sorted(world.present)
        lying_wrong = [world.actual(t) for t in sorted(world.misplaced)]
        response.misplaced_tiles = [t.tile_id for t in lying_wrong]
        response.misplaced_types = [t.type_name for t in lying_wrong]
        response.misplaced_poses = [pose_of(t) for t in lying_wrong]
        response.robots = [Point(x=pose[0], y=pose[1], z=0.0)
                           for robot, pose in self.whereabouts.poses.items() if robot != asking]
        for name in self.overhead_pubs:  # the overhead cameras see every robot at the scan's time
            self.overhead_pubs[name].publish(self.overhead_pose(name, stamp))
        return response

    def on_scan_progress(self, msg: SimScanProgress) -> None:
        stamp = stamp_to_nanoseconds(msg.scan_stamp)
        robot = msg.robot or self.vi_robots[0]
        self.now()  # the pace changes from this moment on
        if msg.stage == SimScanProgress.JUDGED:
            self.hold.judged(stamp, robot, wall=time.monotonic())
            self.event("scan_judged", robot=robot, wall_delay=round(msg.wall_delay, 4), problem=msg.problem)
        elif msg.stage == SimScanProgress.UNJUDGED:
            self.hold.judged(stamp, robot, wall=time.monotonic())
            self.event("scan_unjudged", robot=robot, scan_t=stamp * 1e-9)
        elif msg.stage == SimScanProgress.FAILED:
            self.hold.judged(robot=robot, wall=time.monotonic())

    def overhead_pose(self, name: str, stamp: Any) -> PoseStamped:
        """The overhead cameras' view of a robot: its true pose plus the current error."""
        x, y, yaw = self.cameras.observe(name, self.whereabouts.poses[name])
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = stamp
        pose.pose.position.x, pose.pose.position.y = x, y
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_rotation(_yaw_rotation(yaw))
        return pose


def _yaw_rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def main(args: list[str] | None = None) -> int:
    return run_node(SimWorld, (ValueError, StructureError), args=args, error_prefix="sim_world")


if __name__ == "__main__":
    sys.exit(main())
