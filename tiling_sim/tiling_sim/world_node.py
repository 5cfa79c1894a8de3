"""sim_world: the simulated testbed, the default when no robot is attached (paper section 3).

One process standing in for the physical world: it publishes `/clock` (simulated time running
`real_time_factor` times faster than the wall clock), holds the physical structure S_p, serves
every simulated assembly robot's `place_tile` action with realistic phase durations, drives the
VI robot's base (`/vi/navigate_to`), publishes the overhead localization of every robot with the
paper's errors (up to 5 cm and 10 degrees), runs the Kinect simulator from the VI robot's true
camera pose, and injects faults (tiles removed at random times, tiles dropped while placing).
What happens is published as JSON lines on `/sim/events` for the experiment runner.
"""

from __future__ import annotations

import heapq
import itertools
import json
import math
import random
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import rclpy
from geometry_msgs.msg import PoseStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import PointCloud2, PointField
from std_msgs.msg import Empty, String

from tiling_assembly.geometry import (
    quaternion_from_rotation,
    rotation_from_quaternion,
    rpy_from_rotation,
)
from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.spinning import run_node
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import NavigateTo, PlaceTile
from tiling_assembly_msgs.msg import TileStateArray
from tiling_sim.faults import FaultInjector
from tiling_sim.kinect import ClutterBox, KinectScene, KinectSimulator, PinholeIntrinsics, camera_pose
from tiling_sim.robot_motion import MotionModel, drive_time_to_pose, placement_phases, start_positions
from tiling_sim.sim_clock import Pace, SimClock
from tiling_sim.world import PhysicalWorld, PlaceCheck
from vi_node.point_cloud import cloud_bytes, cloud_fields

CAMERA = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE)
EVENTS = QoSProfile(depth=1000, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)


@dataclass
class OverheadError:
    """The overhead cameras' error for one robot while it stands still (paper: < 5 cm, < 10 deg)."""

    dx: float = 0.0
    dy: float = 0.0
    dyaw: float = 0.0

    @classmethod
    def draw(cls, rng: random.Random, max_position: float, max_yaw: float) -> OverheadError:
        radius = max_position * math.sqrt(rng.random())
        angle = rng.uniform(0, math.tau)
        return cls(radius * math.cos(angle), radius * math.sin(angle), rng.uniform(-max_yaw, max_yaw))


class SimWorld(Node):
    def __init__(self) -> None:
        super().__init__("sim_world")
        self._declare_parameters()
        p = self.get_parameter
        self.structure = load_structure(p("structure_file").value)
        self.world = PhysicalWorld(self.structure)
        self.motion = MotionModel(
            drive_speed=p("drive_speed").value, turn_speed=p("turn_speed").value,
            locate_time=p("locate_time").value, pick_time=p("pick_time").value,
            place_time=p("place_time").value, retreat_time=p("retreat_time").value,
            approach_distance=p("approach_distance").value,
            base_size=tuple(float(v) for v in p("robot_size").value[:2]),
            base_clearance=p("base_clearance").value,
        )
        if self.motion.base_clearance < 0:
            raise ValueError("base_clearance must not be negative")
        # where a base may not stand: on any tile of the structure, placed or not
        self.footprints = [convex_hull_2d(tile.vertices[:, :2]) for tile in self.structure.tiles.values()]
        self.real_time_factor = float(p("real_time_factor").value)
        self.clock_step = float(p("clock_step").value)
        if self.real_time_factor <= 0 or self.clock_step <= 0:
            raise ValueError("real_time_factor and clock_step must be positive")
        self.robots = [r for r in p("robot_names").value if r]
        if not self.robots:
            raise ValueError("robot_names is empty: the world needs at least one assembly robot")
        starts = list(p("robot_start_xy").value)
        if len(starts) < 2:  # automatic
            centres = [(tile.position[0], tile.position[1]) for tile in self.structure.tiles.values()]
            starts = [c for xy in start_positions(centres, len(self.robots)) for c in xy]
        if len(starts) != 2 * len(self.robots):
            raise ValueError(f"robot_start_xy needs 2 numbers per robot ({len(self.robots)}), got {len(starts)}")
        self.positions = {r: (starts[2 * k], starts[2 * k + 1]) for k, r in enumerate(self.robots)}
        vi = list(p("vi_start_pose").value)
        self.vi_pose = (vi[0], vi[1], vi[2])
        self.vi_moving = False
        self.rng = random.Random(int(p("seed").value))
        self.max_position_error = float(p("overhead_position_error").value)
        self.max_yaw_error = math.radians(float(p("overhead_yaw_error_deg").value))
        self.overhead_errors = {
            name: OverheadError.draw(self.rng, self.max_position_error, self.max_yaw_error)
            for name in [*self.robots, "vi"]
        }
        self.faults = FaultInjector.scheduled(
            int(p("seed").value), int(p("removals").value),
            (float(p("removal_window_start").value), float(p("removal_window_end").value)),
            float(p("drop_probability").value),
        )
        self.scan_period = float(p("scan_period").value)
        self.camera_mount = self._camera_mount()
        self.robots_in_view = bool(p("robots_in_view").value)
        self.robot_size = tuple(float(v) for v in p("robot_size").value)

        self.clock = SimClock(self.real_time_factor)
        if not bool(p("wait_for_start").value):
            self.clock.start(time.monotonic())
        self.sleepers: list[tuple[float, int, Callable[[], None]]] = []
        self.sleeper_ids = itertools.count()
        self.lock = threading.RLock()
        self.busy_robots: set[str] = set()
        self.next_scan = self.scan_period
        self.scan_pending = False
        self.awaiting_verdict: tuple[int, float] | None = None  # (stamp ns, wall s) of the last scan sent
        self.arrival_scan_due = False  # the next scan is the one the explorer stopped for
        self.scan_awaited = False  # the scan being rendered or judged is such a scan
        self.verdict_timeout = float(p("verdict_timeout").value)
        self.complete_reported = False

        group = ReentrantCallbackGroup()
        self.clock_pub = self.create_publisher(ClockMsg, "/clock", 10)
        self.event_pub = self.create_publisher(String, "/sim/events", EVENTS)
        self.overhead_pubs = {
            name: self.create_publisher(PoseStamped, f"/{name}/overhead_pose", 10) for name in [*self.robots, "vi"]
        }
        # reliable: Fast DDS loses most fragmented 3.7 MB samples best effort, and the next scan waits
        # for the verdict on this one (vi_node's sensor_reliability auto follows)
        self.cloud_pub = self.create_publisher(PointCloud2, "/vi/camera/depth/points", CAMERA)
        self.servers = [
            ActionServer(
                self, PlaceTile, f"/{robot}/place_tile",
                execute_callback=self._placement_executor(robot),
                goal_callback=lambda goal, r=robot: self.accept_placement(r, goal),
                cancel_callback=lambda _handle: CancelResponse.ACCEPT,
                callback_group=group,
            )
            for robot in self.robots
        ]
        self.navigate_server = ActionServer(
            self, NavigateTo, "/vi/navigate_to", execute_callback=self.execute_navigation,
            cancel_callback=lambda _handle: CancelResponse.ACCEPT, callback_group=group,
        )
        self.scanner = self._make_scanner()
        self.scan_pool = ThreadPoolExecutor(max_workers=1)
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        # one tick at a time: a scan must carry the time of the world it shows
        self.create_timer(self.clock_step, self.tick, clock=steady, callback_group=MutuallyExclusiveCallbackGroup())
        self.create_subscription(Empty, "/sim/start", self.on_start, EVENTS)
        self.create_subscription(TileStateArray, "/tile_states", self.on_verdict, 10, callback_group=group)
        self.event("started", robots=self.robots, structure=self.structure.name,
                   removal_times=[round(t, 1) for t in self.faults.removal_times])
        self.get_logger().info(
            f"simulating {self.structure.name} with {', '.join(self.robots)} and the VI robot at "
            f"{self.real_time_factor:g}x real time; {len(self.faults.removal_times)} removals scheduled"
        )

    # --- parameters -------------------------------------------------------------------------
    def _declare_parameters(self) -> None:
        def declare(name: str, default: object, description: str) -> None:
            self.declare_parameter(name, default, ParameterDescriptor(description=description))

        declare("structure_file", "", "Structure YAML being built (required).")
        declare("robot_names", ["robot1", "robot2"], "Simulated assembly robots (one place_tile server each).")
        declare("robot_start_xy", [0.0], "x1, y1, x2, y2, ... start positions of the robots in map (m); "
                "fewer than 2 numbers: spread on a circle around the structure.")
        declare("vi_start_pose", [1.0, 0.0, math.pi], "x, y, yaw of the VI robot's base at the start.")
        declare("real_time_factor", 20.0, "How much faster than the wall clock simulated time runs (at the wall "
                "clock's pace while a scan awaits vi_node's verdict: the inspection's real cost).")
        declare("clock_step", 0.005, "s of wall-clock time between two /clock messages.")
        declare("drive_speed", 0.15, "Base speed, m/s.")
        declare("turn_speed", 1.0, "Base turning speed, rad/s.")
        declare("locate_time", 2.0, "s to find a tile with the laser at its cache.")
        declare("pick_time", 6.0, "s to pick a tile.")
        declare("place_time", 10.0, "s to place a tile.")
        declare("retreat_time", 2.0, "s to back off after placing.")
        declare("approach_distance", 0.25, "m from a tile's centre to where the base stops to place it "
                "(further out if the base would stand on the structure).")
        declare("base_clearance", 0.03, "m an assembly robot's base keeps from every tile of the structure.")
        declare("wait_for_start", False, "Hold simulated time at 0 until a message on /sim/start.")
        declare("seed", 1, "Seed of every random choice of the world (faults, localization errors, noise).")
        declare("removals", 0, "Tiles to remove during the build.")
        declare("removal_window_start", 40.0, "s of simulated time from which removals may happen.")
        declare("removal_window_end", 200.0, "s of simulated time by which removals happen.")
        declare("drop_probability", 0.0, "Chance that a tile slips from the gripper during a placement.")
        declare("overhead_position_error", 0.05, "Largest overhead localization error, m.")
        declare("overhead_yaw_error_deg", 10.0, "Largest overhead heading error, degrees.")
        declare("scan_period", 1.0, "s of simulated time between two Kinect scans while the VI robot stands.")
        declare("verdict_timeout", 3.0, "The next scan waits for vi_node's verdict on the last one (/tile_states) "
                "or this many s of wall-clock time: the simulated camera streams what the inspection consumes.")
        # the same names as vi_node's: the runner gives both nodes config/vi_node.yaml
        declare("camera_xyz", [0.08, 0.0, 0.55], "Pose of camera_link in the VI robot's base_link: x, y, z (m).")
        declare("camera_rpy", [0.0, 0.45, 0.0], "Pose of camera_link in base_link: roll, pitch, yaw (rad).")
        declare("intrinsics", [580.0, 580.0, 319.5, 239.5], "Kinect depth camera fx, fy, cx, cy (px).")
        declare("intrinsics_size", [640, 480], "Kinect depth image width, height (px).")
        declare("robots_in_view", True, "The assembly robots appear in the Kinect's view (as boxes).")
        declare("robot_size", [0.33, 0.33, 0.35], "Box standing for an assembly robot: x, y, z size (m).")

    def _camera_mount(self) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        xyz = tuple(float(v) for v in self.get_parameter("camera_xyz").value)
        rpy = tuple(float(v) for v in self.get_parameter("camera_rpy").value)
        if len(xyz) != 3 or len(rpy) != 3:
            raise ValueError("camera_xyz and camera_rpy need 3 numbers each")
        return xyz, rpy  # type: ignore[return-value]

    def _make_scanner(self) -> KinectSimulator:
        fx, fy, cx, cy = (float(v) for v in self.get_parameter("intrinsics").value)
        width, height = (int(v) for v in self.get_parameter("intrinsics_size").value)
        intrinsics = PinholeIntrinsics(fx, fy, cx, cy, width, height)
        return KinectSimulator(intrinsics, seed=int(self.get_parameter("seed").value))

    # --- simulated time -----------------------------------------------------------------------
    @property
    def sim_now(self) -> float:
        return self.clock.now

    def pace(self) -> Pace:
        """The explorer waits at its viewpoint for the scan it stopped for: time stops while the scan
        is rendered (a Kinect delivers at once) and runs at the wall clock's pace while it is judged."""
        if not self.scan_awaited:
            return Pace.FAST
        if self.scan_pending:
            return Pace.STOPPED
        return Pace.REAL if self.awaiting_verdict is not None else Pace.FAST

    def on_start(self, _msg: Empty) -> None:
        if not self.clock.running:
            self.clock.start(time.monotonic())
            self.get_logger().info("start: simulated time runs")

    def tick(self) -> None:
        with self.lock:
            now = self.clock.advance(time.monotonic(), self.pace())
            msg = ClockMsg()
            msg.clock.sec = int(now)
            msg.clock.nanosec = int((now % 1.0) * 1e9)
            self.clock_pub.publish(msg)
            due = []
            while self.sleepers and self.sleepers[0][0] <= now:
                due.append(heapq.heappop(self.sleepers)[2])
        for wake in due:
            wake()
        self.inject_faults()
        self.maybe_scan()

    def sleep(self, duration: float) -> Future:
        """A future done after `duration` s of simulated time."""
        future = Future()
        with self.lock:
            heapq.heappush(self.sleepers, (self.sim_now + max(duration, 0.0), next(self.sleeper_ids),
                                           lambda: future.done() or future.set_result(True)))
        return future

    def stamp(self):  # type: ignore[no-untyped-def]
        return rclpy.time.Time(nanoseconds=int(self.sim_now * 1e9)).to_msg()

    def event(self, kind: str, **fields: object) -> None:
        self.event_pub.publish(String(data=json.dumps({"t": round(self.sim_now, 3), "event": kind, **fields})))

    # --- faults -------------------------------------------------------------------------------
    def inject_faults(self) -> None:
        with self.lock:
            if not self.faults.due(self.sim_now):
                return
            tile_id = self.faults.choose(self.world.removable())
            if tile_id is None:
                return  # nothing to take yet: try again on the next tick
            self.faults.removed()
            self.world.remove(tile_id)
            self.complete_reported = False
        self.get_logger().info(f"fault: tile {tile_id} removed from the structure")
        self.event("removed", tile=tile_id)

    # --- assembly robots ----------------------------------------------------------------------
    def _placement_executor(self, robot: str):  # type: ignore[no-untyped-def]
        # a coroutine function of its own per robot: rclpy awaits only real coroutine functions
        async def execute(handle) -> PlaceTile.Result:  # type: ignore[no-untyped-def]
            return await self.execute_placement(robot, handle)

        return execute

    def accept_placement(self, robot: str, goal: PlaceTile.Goal) -> GoalResponse:
        if robot in self.busy_robots:
            self.get_logger().warn(f"{robot} is busy: refusing a second place_tile goal")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    async def execute_placement(self, robot: str, handle) -> PlaceTile.Result:  # type: ignore[no-untyped-def]
        goal: PlaceTile.Goal = handle.request
        result = PlaceTile.Result()
        start_sim = self.sim_now
        self.busy_robots.add(robot)
        try:
            with self.lock:
                check, reason = self.world.check_placement(goal.tile_id)
            if check is PlaceCheck.ALREADY_PRESENT:
                self.event("already_present", tile=goal.tile_id, robot=robot)
                result.error_code, result.message = PlaceTile.Result.ALREADY_PRESENT, reason
                handle.succeed()
                return result
            if check is PlaceCheck.UNKNOWN_TILE:
                result.error_code, result.message = PlaceTile.Result.FAILED_PRECONDITION, reason
                handle.abort()
                return result
            self.event("place_started", tile=goal.tile_id, robot=robot)
            tile_xy = (goal.pose.pose.position.x, goal.pose.pose.position.y)
            phases = placement_phases(
                self.motion, self.positions[robot], (goal.cache.x, goal.cache.y), tile_xy, self.footprints
            )
            for phase in phases:
                feedback = PlaceTile.Feedback(phase=phase.phase, phase_progress=0.0)
                feedback.robot_pose = self.overhead_pose(robot)
                handle.publish_feedback(feedback)
                await self.sleep(phase.duration)
                self.positions[robot] = phase.end
                self.overhead_errors[robot] = OverheadError.draw(self.rng, self.max_position_error, self.max_yaw_error)
                if handle.is_cancel_requested:
                    result.error_code, result.message = PlaceTile.Result.CANCELED, "canceled"
                    handle.canceled()
                    return result
                if phase.phase == PlaceTile.Feedback.PICKING and self.faults.drops():
                    self.event("dropped", tile=goal.tile_id, robot=robot)
                    result.error_code = PlaceTile.Result.FAILED_GRASP
                    result.message = f"tile {goal.tile_id} slipped from {robot}'s gripper"
                    handle.abort()
                    return result
                if phase.phase == PlaceTile.Feedback.PLACING:
                    with self.lock:
                        check, reason = self.world.check_placement(goal.tile_id)
                        if check is PlaceCheck.OK:
                            self.world.place(goal.tile_id)
                        absent = self.world.absent_supports(goal.tile_id)
                    if check is PlaceCheck.ALREADY_PRESENT:
                        self.event("already_present", tile=goal.tile_id, robot=robot)
                        result.error_code, result.message = PlaceTile.Result.ALREADY_PRESENT, reason
                        handle.succeed()
                        return result
                    if check is not PlaceCheck.OK:
                        self.event("refused", tile=goal.tile_id, robot=robot, reason=reason)
                        result.error_code = PlaceTile.Result.FAILED_PRECONDITION
                        result.message = reason
                        result.missing_supports = absent
                        handle.abort()
                        return result
                    self.event("placed", tile=goal.tile_id, robot=robot)
            result.error_code = PlaceTile.Result.SUCCEEDED
            result.placed_pose = goal.pose
            handle.succeed()
            with self.lock:
                if self.world.complete() and not self.complete_reported:
                    self.complete_reported = True
                    self.event("complete", pending_removals=len(self.faults.removal_times))
            return result
        finally:
            result.duration = self.sim_now - start_sim
            self.busy_robots.discard(robot)

    def overhead_pose(self, name: str) -> PoseStamped:
        """The overhead cameras' view of a robot: true pose plus the current error."""
        error = self.overhead_errors[name]
        if name == "vi":
            x, y, yaw = self.vi_pose
        else:
            (x, y), yaw = self.positions[name], 0.0
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = self.stamp()
        pose.pose.position.x, pose.pose.position.y = x + error.dx, y + error.dy
        q = quaternion_from_rotation(_yaw_rotation(yaw + error.dyaw))
        pose.pose.orientation.x, pose.pose.orientation.y, pose.pose.orientation.z, pose.pose.orientation.w = q
        return pose

    # --- VI robot -----------------------------------------------------------------------------
    async def execute_navigation(self, handle) -> NavigateTo.Result:  # type: ignore[no-untyped-def]
        target = handle.request.target.pose
        yaw = rpy_from_rotation(rotation_from_quaternion(
            target.orientation.x, target.orientation.y, target.orientation.z, target.orientation.w))[2]
        goal = (target.position.x, target.position.y, yaw)
        self.vi_moving = True
        duration = drive_time_to_pose(self.motion, self.vi_pose, goal)
        feedback = NavigateTo.Feedback(distance_remaining=float(math.dist(self.vi_pose[:2], goal[:2])))
        feedback.current_pose = self.overhead_pose("vi")
        handle.publish_feedback(feedback)
        await self.sleep(duration)
        self.vi_pose = goal
        self.overhead_errors["vi"] = OverheadError.draw(self.rng, self.max_position_error, self.max_yaw_error)
        self.vi_moving = False
        self.next_scan = self.sim_now + 0.2  # let the base settle before the next scan
        self.arrival_scan_due = True
        result = NavigateTo.Result(success=True)
        result.final_pose = self.overhead_pose("vi")
        handle.succeed()
        return result

    def on_verdict(self, msg: TileStateArray) -> None:
        """vi_node has judged a scan (states or the reason it has none): the camera may take the next."""
        awaiting = self.awaiting_verdict
        if awaiting is not None and msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec >= awaiting[0]:
            self.awaiting_verdict = None
            self.scan_awaited = False
            delay = time.monotonic() - awaiting[1]
            self.event("scan_judged", wall_delay=round(delay, 4), problem=msg.problem)

    def maybe_scan(self) -> None:
        awaiting = self.awaiting_verdict
        if awaiting is not None and time.monotonic() - awaiting[1] > self.verdict_timeout:
            self.awaiting_verdict = None  # no inspection listens, or it is stuck: do not wait for it
            self.scan_awaited = False
            self.event("scan_unjudged", scan_t=awaiting[0] * 1e-9)
            self.get_logger().warn(f"no verdict on the scan of t={awaiting[0] * 1e-9:.2f} s within "
                                   f"{self.verdict_timeout:g} s: taking the next one")
        if self.vi_moving or self.scan_pending or self.awaiting_verdict is not None or self.sim_now < self.next_scan:
            return
        if self.cloud_pub.get_subscription_count() == 0:
            return  # nobody looks: rendering would only cost
        self.next_scan = self.sim_now + self.scan_period
        self.scan_awaited, self.arrival_scan_due = self.arrival_scan_due, False
        self.scan_pending = True
        with self.lock:
            present = sorted(self.world.present)
            robots = [] if not self.robots_in_view else [
                ClutterBox((x, y, self.robot_size[2] / 2), self.robot_size) for x, y in self.positions.values()
            ]
            stamp = self.stamp()
        for name, publisher in self.overhead_pubs.items():  # the overhead cameras see every robot
            publisher.publish(self.overhead_pose(name))
        x, y, yaw = self.vi_pose
        pose = camera_pose(x, y, yaw, *self.camera_mount)
        self.scan_pool.submit(self.scan, present, robots, pose, stamp)

    def scan(self, present: list[int], robots: list[ClutterBox], pose: np.ndarray, stamp) -> None:  # type: ignore[no-untyped-def]
        """One Kinect frame from the VI robot's true camera pose (runs on the scan thread)."""
        try:
            scene = KinectScene.from_structure(self.structure, present, clutter=robots)
            cloud = self.scanner.scan(scene, pose)
            msg = PointCloud2(height=cloud.shape[0], width=cloud.shape[1], is_bigendian=False,
                              point_step=12, row_step=12 * cloud.shape[1], is_dense=False)
            msg.header.stamp = stamp
            msg.header.frame_id = "camera_depth_optical_frame"
            msg.fields = [PointField(name=n, offset=o, datatype=d, count=c) for n, o, d, c in cloud_fields()]
            msg.data = cloud_bytes(cloud)
            if self.context.ok():  # not shut down while the frame was rendered
                self.awaiting_verdict = (stamp.sec * 10**9 + stamp.nanosec, time.monotonic())
                self.cloud_pub.publish(msg)
        except Exception as error:
            if self.context.ok():
                self.get_logger().error(f"Kinect simulation failed: {error}")
        finally:
            self.scan_pending = False


def _yaw_rotation(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def main(args: list[str] | None = None) -> int:
    return run_node(SimWorld, (ValueError, StructureError), args=args, error_prefix="sim_world",
                    executor=lambda: MultiThreadedExecutor(num_threads=3),
                    on_shutdown=lambda node: node.scan_pool.shutdown(wait=True, cancel_futures=True))


if __name__ == "__main__":
    sys.exit(main())
