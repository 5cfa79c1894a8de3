"""sim_vi: a simulated VI robot's body, on board the robot (run in its namespace: /vi, or /vi1, /vi2, ...).

Serves the base's `navigate_to` (turn, drive, turn at the speeds of `config/tiling_sim.yaml`,
sleeping on simulated time) and is its Kinect: while the base stands, it takes a frame when one is
due (`scan_cycle`: every `scan_period` s, never before vi_node judged the last one), asks the world
for a snapshot (`/sim/snapshot`: tiles in place, where the assembly robots truly stand, the time),
renders it from its own true camera pose on a thread of its own (`kinect`) and publishes it on
`camera/depth/points` here, on the robot: a 3.7 MB cloud never crosses the robots' network (and,
with `record_scans`, writes it to a rosbag2 with its true poses and the world's truth). It
tells the world how each frame fares (`/sim/scan_progress`), which paces the clock for the frame
the explorer stopped for after an arrival (stopped while it renders, wall pace while judged). Of the
verdicts on `/tile_states` it takes its own robot's (`robot_name`): with several VI robots, another's
verdict says nothing about this camera's frame.
"""

from __future__ import annotations

import math
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import numpy as np
from geometry_msgs.msg import Pose, PoseStamped
from rclpy.action import ActionServer, CancelResponse
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header

from tiling_assembly.geometry import (
    PlacedTile,
    quaternion_from_rotation,
    rotation_from_quaternion,
    rotation_from_rpy,
    rpy_from_rotation,
)
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import NavigateTo
from tiling_assembly_msgs.msg import SimMotion, SimScanProgress, TileStateArray
from tiling_assembly_msgs.srv import SimSnapshot
from tiling_ros.parameters import declare_settings
from tiling_ros.point_clouds import cloud_to_msg
from tiling_ros.qos import SIM_CAMERA, SIM_MOTION, SIM_SCAN_PROGRESS
from tiling_ros.spinning import run_node
from tiling_ros.stamps import stamp_from_seconds, stamp_to_nanoseconds
from tiling_sim import sim_interface as sim
from tiling_sim.kinect import ClutterBox, KinectScene, KinectSimulator, PinholeIntrinsics, camera_pose
from tiling_sim.robot_motion import drive_time_to_pose
from tiling_sim.scan_bag import ScanBagWriter
from tiling_sim.scan_cycle import Frame, ScanCycle
from tiling_sim.sim_settings import ViBodySettings
from tiling_sim.whereabouts import standing_at

# reliable: Fast DDS loses most fragmented 3.7 MB samples best effort, and the next frame waits for
# the verdict on this one (vi_node's sensor_reliability auto follows)
OPTICAL_FRAME = "camera_depth_optical_frame"  # the frame of the Kinect's clouds
Pose2 = tuple[float, float, float]


class SimVi(Node):
    def __init__(self) -> None:
        super().__init__("sim_vi")
        self.settings: ViBodySettings = declare_settings(
            self, ViBodySettings, dynamic_typing=True, build=ViBodySettings.from_values
        )
        s = self.settings
        self.name = self.get_namespace().strip("/")
        if not self.name:
            raise ValueError("sim_vi runs in the VI robot's namespace (-r __ns:=/vi)")
        self.structure = load_structure(s.structure_file)
        self.motion = s.motion()
        starts = s.vi_starts(self.structure)
        if self.name not in starts:
            raise ValueError(f"sim_vi in /{self.name}: not one of vi_robot_names ({', '.join(s.vi_team)})")
        self.pose: Pose2 = starts[self.name]
        self.drive: tuple[float, Pose2] | None = None  # (arrive_at, goal) of the drive under way
        fx, fy, cx, cy = s.intrinsics
        width, height = s.intrinsics_size
        self.kinect = KinectSimulator(PinholeIntrinsics(fx, fy, cx, cy, width, height), seed=s.seed)
        self.mount = (tuple(s.camera_xyz), tuple(s.camera_rpy))
        self.cycle = ScanCycle(s.scan_period, s.verdict_timeout)
        self.lock = threading.Lock()  # the cycle, between the executor and the render thread
        self.render_pool = ThreadPoolExecutor(max_workers=1)
        if s.record_scans and Path(s.record_scans).exists():
            raise ValueError(f"record_scans: {s.record_scans} exists; a recording needs a new folder")
        self.recording = ScanBagWriter(s.record_scans).__enter__() if s.record_scans else None
        self.recording_lock = threading.Lock()  # frames from the render thread, poses from the executor
        if self.recording is not None:  # the overhead poses as the team sees them (with their errors)
            for robot in (self.name, *[r for r in (*s.team, *s.vi_team) if r != self.name]):
                self.create_subscription(PoseStamped, f"/{robot}/overhead_pose",
                                         lambda msg, robot=robot: self.record_pose(robot, msg), 10)
        self.time = sim.SimTime(self, on_tick=self.tick)
        self.world = self.create_client(SimSnapshot, sim.SNAPSHOT)
        self.motion_pub = self.create_publisher(SimMotion, sim.MOTION, SIM_MOTION)
        self.progress_pub = self.create_publisher(SimScanProgress, sim.SCAN_PROGRESS, SIM_SCAN_PROGRESS)
        self.cloud_pub = self.create_publisher(PointCloud2, "camera/depth/points", SIM_CAMERA)
        self.create_subscription(TileStateArray, "/tile_states", self.on_verdict, 10)
        # served from the start: the explorer's client and this server discover each other early (the
        # base needs no answer of the world: where it will stand is kept for the world, see MOTION_QOS)
        self.server = ActionServer(self, NavigateTo, "navigate_to", execute_callback=self.navigate,
                                   cancel_callback=lambda _handle: CancelResponse.ACCEPT)
        self.get_logger().info(f"serving {self.resolve_topic_name('navigate_to')} and the Kinect on "
                               f"{self.resolve_topic_name('camera/depth/points')}")

    # --- the base -----------------------------------------------------------------------------
    async def navigate(self, handle: Any) -> NavigateTo.Result:
        target = handle.request.target.pose
        o = target.orientation
        yaw = rpy_from_rotation(rotation_from_quaternion(o.x, o.y, o.z, o.w))[2]
        goal = (target.position.x, target.position.y, yaw)
        with self.lock:
            # set off at the time of the frame the goal was decided on (see ScanCycle.departure), not
            # when the goal came; no frames meanwhile: the world's clock waits at the next frame's time
            depart_at = self.cycle.departure(stamp_to_nanoseconds(handle.request.target.header.stamp),
                                             self.time.now)
            self.cycle.departed()
            # a frame the world waits for comes on arrival only when vi_node answers (see ScanCycle)
            framed = self.cycle.answering and self.cloud_pub.get_subscription_count() > 0
        feedback = NavigateTo.Feedback(distance_remaining=float(math.dist(self.pose[:2], goal[:2])))
        feedback.current_pose = self.pose_msg(self.time.now)
        handle.publish_feedback(feedback)
        if depart_at > self.time.now:
            await self.time.until(depart_at)
        arrive_at = depart_at + drive_time_to_pose(self.motion, self.pose, goal)
        self.motion_pub.publish(SimMotion(robot=self.name, arrive_at=arrive_at, x=goal[0], y=goal[1], yaw=goal[2],
                                          busy=framed))
        with self.lock:
            self.drive = (arrive_at, goal)
        await self.time.until(arrive_at)
        with self.lock:
            self.pose, self.drive = goal, None
            # the base settles, then the frame the explorer waits for: counted from the arrival the world
            # was told of (this body may wake late; the world holds its clock for that frame, see scan_hold)
            self.cycle.arrived(arrive_at)
        result = NavigateTo.Result(success=True)
        # stamped with the arrival the world was told of, not when this body woke (later on a busy host):
        # the explorer counts the frame the world holds at the arrival + settle as taken there
        result.final_pose = self.pose_msg(arrive_at)
        handle.succeed()
        return result

    def pose_msg(self, at: float) -> PoseStamped:
        """Where the base is at `at` (s): the body knows its own pose exactly (the overhead view is
        the world's)."""
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = stamp_from_seconds(at)
        pose.pose.position.x, pose.pose.position.y = self.pose[0], self.pose[1]
        o = pose.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_rotation(rotation_from_rpy(0.0, 0.0, self.pose[2]))
        return pose

    # --- the Kinect ---------------------------------------------------------------------------
    def tick(self) -> None:
        """A new simulated time: give up a frame that waited too long, or take the next one."""
        if not self.world.service_is_ready():
            return  # the world does not answer yet
        with self.lock:
            overdue = self.cycle.overdue(time.monotonic())
            looked_at = self.cloud_pub.get_subscription_count() > 0  # else rendering would only cost
            frame = self.cycle.start(self.time.now, time.monotonic()) if looked_at else None
            hold_for = self.settings.scan_period if self.cycle.answering else 0.0  # nobody to wait for
        if overdue is not None:
            self.give_up(overdue)
        if frame is not None:
            request = SimSnapshot.Request(hold_clock=frame.held, robot=self.name, hold_for=hold_for,
                                          decision_window=self.settings.decision_window)
            self.world.call_async(request).add_done_callback(lambda future: self.on_snapshot(frame, future))

    def on_snapshot(self, frame: Frame, future: Any) -> None:
        snapshot: SimSnapshot.Response | None = future.result()
        with self.lock:
            # where the world has the base at the snapshot's time: this body's clock may lag the world's,
            # and a frame rendered from where the body thought it was lay a whole drive off its overhead pose
            if snapshot is None or not self.cycle.snapshot_arrived(frame, stamp_to_nanoseconds(snapshot.stamp)):
                return
            pose = standing_at(stamp_to_nanoseconds(snapshot.stamp) * 1e-9, self.pose, self.drive)
        self.render_pool.submit(self.render, frame, snapshot, pose)

    def render(self, frame: Frame, snapshot: SimSnapshot.Response, pose: Pose2) -> None:
        """One Kinect frame of the snapshot's world from the camera's true pose (on the render thread)."""
        try:
            cloud = self.kinect.scan(self.scene(snapshot), camera_pose(*pose, *self.mount))
            if not self.context.ok():
                return  # shut down while the frame was rendered
            with self.lock:
                self.cycle.published(frame, time.monotonic())
            self.cloud_pub.publish(cloud_to_msg(cloud, Header(stamp=snapshot.stamp, frame_id=OPTICAL_FRAME)))
            self.progress(SimScanProgress.PUBLISHED, frame)
            if self.recording is not None:
                self.record(cloud, snapshot, pose)
        except Exception as error:
            if self.context.ok():
                self.get_logger().error(f"Kinect simulation failed: {error}")
                with self.lock:
                    self.cycle.failed(frame)
                self.progress(SimScanProgress.FAILED, frame)

    def record_pose(self, robot: str, msg: PoseStamped) -> None:
        o = msg.pose.orientation
        yaw = rpy_from_rotation(rotation_from_quaternion(o.x, o.y, o.z, o.w))[2]
        with self.recording_lock:
            if self.recording is not None:
                self.recording.write_pose(stamp_to_nanoseconds(msg.header.stamp), msg.pose.position.x,
                                          msg.pose.position.y, yaw, robot="vi" if robot == self.name else robot)

    def record(self, cloud: Any, snapshot: SimSnapshot.Response, pose: Pose2) -> None:
        """Write the frame to the bag (its overhead poses are written as they come, see
        `record_pose`), and to truth.json the camera's true pose, the other robots' true positions
        and what lay where (on the render thread, after publishing)."""
        stamp = stamp_to_nanoseconds(snapshot.stamp)
        lying_wrong = [{"tile": int(t), "type": type_name, "x": p.position.x, "y": p.position.y,
                        "yaw": rpy_from_rotation(rotation_from_quaternion(p.orientation.x, p.orientation.y,
                                                                          p.orientation.z, p.orientation.w))[2]}
                       for t, type_name, p in zip(snapshot.misplaced_tiles, snapshot.misplaced_types,
                                                  snapshot.misplaced_poses, strict=True)]
        with self.recording_lock:
            if self.recording is not None:
                self.recording.write_scan(stamp, cloud, {
                    "robot": self.name, "pose": list(pose), "present": [int(t) for t in snapshot.present_tiles],
                    "lying_wrong": lying_wrong, "robots": [[r.x, r.y] for r in snapshot.robots]})

    def close_recording(self) -> None:
        with self.recording_lock:
            if self.recording is not None:
                self.recording.set_truth(structure_file=self.settings.structure_file,
                                         camera_xyz=list(self.mount[0]), camera_rpy=list(self.mount[1]))
                self.recording.__exit__(None, None, None)
                self.recording = None

    def scene(self, snapshot: SimSnapshot.Response) -> KinectScene:
        size = tuple(self.settings.robot_size)
        robots = [ClutterBox((p.x, p.y, size[2] / 2), size) for p in snapshot.robots]
        lying_wrong = {int(t): self.real_tile(int(t), type_name, pose) for t, type_name, pose in
                       zip(snapshot.misplaced_tiles, snapshot.misplaced_types, snapshot.misplaced_poses, strict=True)}
        tiles = [lying_wrong.get(t) or self.structure.tiles[t] for t in snapshot.present_tiles
                 if t in self.structure.tiles]
        return KinectScene(tiles, clutter=robots if self.settings.robots_in_view else [])

    def real_tile(self, tile_id: int, type_name: str, pose: Pose) -> PlacedTile:
        """A tile as it really lies (shifted, turned, or a tile of another type in its place)."""
        shape = self.structure.tile_types[type_name].shape
        q, p = pose.orientation, pose.position
        return PlacedTile(tile_id, type_name, shape, rotation_from_quaternion(q.x, q.y, q.z, q.w),
                          np.array([p.x, p.y, p.z]))

    def on_verdict(self, msg: TileStateArray) -> None:
        """vi_node has judged a scan (states or the reason it has none): the camera may take the next."""
        if msg.robot_name and msg.robot_name != self.name:
            return
        with self.lock:
            judged = self.cycle.judged(stamp_to_nanoseconds(msg.header.stamp), time.monotonic())
        if judged is not None:
            frame, delay = judged
            self.progress(SimScanProgress.JUDGED, frame, wall_delay=delay, problem=msg.problem)

    def give_up(self, frame: Frame) -> None:
        if frame.stamp_ns == 0:
            self.get_logger().warn("the world did not answer a snapshot in time: taking the next frame")
            self.progress(SimScanProgress.FAILED, frame)
            return
        self.get_logger().warn(f"no verdict on the scan of t={frame.stamp_ns * 1e-9:.2f} s in time: taking the "
                               "next one")
        self.progress(SimScanProgress.UNJUDGED, frame)

    def progress(self, stage: int, frame: Frame, wall_delay: float = 0.0, problem: str = "") -> None:
        """Tell the world how `frame` fares (a frame without a snapshot releases any hold)."""
        self.progress_pub.publish(SimScanProgress(stage=stage, robot=self.name,
                                                  scan_stamp=stamp_from_seconds(frame.stamp_ns * 1e-9),
                                                  wall_delay=wall_delay, problem=problem))


def main(args: list[str] | None = None) -> int:
    return run_node(SimVi, (ValueError, StructureError), args=args, error_prefix="sim_vi",
                    on_shutdown=_stop_camera)


def _stop_camera(node: SimVi) -> None:
    node.render_pool.shutdown(wait=True, cancel_futures=True)
    node.close_recording()  # after the last frame: the bag ends with whole frames


if __name__ == "__main__":
    sys.exit(main())
