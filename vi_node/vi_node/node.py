"""`vi_node`: the visual inspection node, a thin adapter over `pipeline.InspectionPipeline`.

Run in the VI robot's namespace (`ros2 run vi_node vi_node --ros-args -r __ns:=/vi --params-file
config/vi_node.yaml`). Subscribes `camera/depth/points` (sensor_msgs/PointCloud2, organized,
camera_depth_optical_frame) and `overhead_pose` (geometry_msgs/PoseStamped, map), and the team's
`/structure`, `/placement_reports`, `/auction/announcements` and `/robot_status`, and the `overhead_pose` of every
other robot (`/<robot>/overhead_pose`: those named in `other_robots`, or every one that appears; the
inspection leaves out what they hide); publishes `/tile_states`
(one TileStateArray per classified scan, `robot_name` this robot's namespace: several VI robots
share the topic), `/tile_markers` (tiles coloured by state, for RViz) and
`/diagnostics`.

S_a: the tiles claimed placed (PlacementReport OUTCOME_PLACED) of the structure on `/structure`;
until a structure / a report arrives, the `structure_file` and `expected_tiles` parameters. A tile
announced in an auction leaves S_a until a new placement report for it arrives; a tile announced for
repair stays until its robot reports it taken off. A tile a robot was placing shortly before a scan
may lie there unreported, and one reported placed after the scan was taken may not have been there
yet: both are expected, but not judged (`tiles_in_hand`). Each scan is paired
with the overhead pose nearest in time; only the latest scan is kept while one is processed (the
camera is faster than the inspection can be on a bad day: old scans are dropped, not queued).
"""

from __future__ import annotations

import sys
import threading
import time
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Point, PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA, Header
from visualization_msgs.msg import Marker, MarkerArray

from tiling_assembly.geometry import PlacedTile, quaternion_from_rotation
from tiling_assembly.messages import structure_from_msg
from tiling_assembly.structure import Structure as StructureModel
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import (
    AuctionAnnouncement,
    PlacementReport,
    RobotStatus,
    Structure,
    TileState,
    TileStateArray,
)
from tiling_ros import team_topics as topics
from tiling_ros.parameters import declare_settings
from tiling_ros.point_clouds import CloudError, cloud_from_msg
from tiling_ros.qos import LATCHED, sensor_stream
from tiling_ros.spinning import run_node
from tiling_ros.stamps import stamp_to_nanoseconds
from vi_node.classify import TileState as State
from vi_node.fusion import TileFusion, fuse_scan
from vi_node.inspection_settings import InspectionSettings, SettingsError, parse_tile_ids
from vi_node.misplacement import moved_tile
from vi_node.other_robots import OtherRobots
from vi_node.pipeline import InspectionPipeline, InspectionStoppedError
from vi_node.pose_matching import PoseBuffer, TeamPoses
from vi_node.pose_prior import OverheadPose
from vi_node.scan_result import ScanResult
from vi_node.tiles_in_hand import TilesInHand

OPTICAL_FRAME = "camera_depth_optical_frame"
COLOURS = {  # RViz colours of the tile states
    State.PRESENT: (0.1, 0.8, 0.1, 0.9),
    State.MISSING: (0.9, 0.1, 0.1, 0.9),
    State.OCCLUDED: (0.95, 0.85, 0.1, 0.9),
    State.MISPLACED: (0.95, 0.45, 0.0, 0.9),
    State.UNKNOWN: (0.6, 0.6, 0.6, 0.5),
}


MEASURED_COLOUR = (0.95, 0.45, 0.0, 0.35)  # where a misplaced tile really is


class StartupError(RuntimeError):
    """A bad parameter or file at start-up: one line, then exit non-zero."""


class ViNode(Node):
    def __init__(self) -> None:
        super().__init__("vi_node")
        self.robot_name = self.get_namespace().strip("/")  # which VI robot's scans these are
        self.settings = self._declare_settings()
        self.structure: StructureModel | None = None
        if self.settings.structure_file:
            try:
                self.structure = load_structure(self.settings.structure_file)
            except StructureError as error:
                raise StartupError(f"structure_file: {error}") from None
        self.parameter_expected: list[int] | None = None
        if self.settings.expected_tiles.strip().lower() != "all":
            self.parameter_expected = parse_tile_ids(self.settings.expected_tiles)
        self.placed: dict[int, int] = {}  # tile id -> stamp (ns) of its latest placement report
        self.withdrawn: dict[int, int] = {}  # tile id -> stamp (ns) of the auction that took it out of S_a
        self.reports_seen = False
        # what the state callbacks learn of S_a, applied by the inspection thread between two scans
        self.news_lock = threading.Lock()
        self.expected_changed = False
        self.to_forget: list[int] = []
        self.in_hand = TilesInHand(int(self.settings.in_hand_memory * 1e9))
        self.pipeline: InspectionPipeline | None = None
        self.fusion = TileFusion()
        self.poses = PoseBuffer()
        self.team = TeamPoses()
        # the latest scan not yet inspected, handed from the cloud callback to the inspection thread
        self.pending: PointCloud2 | None = None
        self.pending_since = 0.0
        self.wake = threading.Condition()  # guards `pending`, `woken`, `closing`
        self.woken = False
        self.closing = False
        self.inspection_thread = threading.Thread(target=self._inspect_scans, name="inspection", daemon=True)

        self.sensor_subscriptions: dict[str, tuple[Any, ReliabilityPolicy]] = {}
        self._match_sensor_publishers()
        self.create_subscription(Structure, "/structure", self._on_structure, LATCHED)
        self.create_subscription(PlacementReport, "/placement_reports", self._on_report, 100)
        self.create_subscription(AuctionAnnouncement, "/auction/announcements", self._on_announcement, 50)
        topics.ROBOT_STATUS.subscribe(self, self._on_robot_status)
        self.states_pub = self.create_publisher(TileStateArray, "/tile_states", 10)
        self.markers_pub = self.create_publisher(MarkerArray, "/tile_markers", 10)
        self.diagnostics_pub = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        # the middleware's graph, not the world: on the steady clock (a simulated clock that has not started,
        # or a paused bag, would leave a reliable cloud on a best-effort reader, which loses it)
        graph = Clock(clock_type=ClockType.STEADY_TIME)
        if self.settings.sensor_reliability == "auto":
            self.create_timer(0.5, self._match_sensor_publishers, clock=graph)
        self.other_robots = OtherRobots(
            self, self.settings.other_robots, self.team.add, lambda line: self._diagnose(DiagnosticStatus.WARN, line)
        )
        self.other_robots.follow()
        self.create_timer(1.0, self.other_robots.follow, clock=graph)
        self._update_expected()
        self._apply_news()
        self.inspection_thread.start()
        self.get_logger().info(
            f"inspecting in {self.settings.mode} mode; structure: "
            f"{self.structure.name if self.structure else 'waiting for /structure'}"
        )

    # -- parameters -------------------------------------------------------------------------------
    def _declare_settings(self) -> InspectionSettings:
        try:
            return declare_settings(
                self, InspectionSettings, dynamic_typing=True,
                build=lambda values: InspectionSettings().with_values(dict(values), "vi_node"),
            )
        except SettingsError as error:
            raise StartupError(str(error)) from None

    # -- S_a --------------------------------------------------------------------------------------
    def _expected_ids(self) -> list[int] | None:
        if self.structure is None:
            return None
        if self.reports_seen:
            ids = [t for t, placed in self.placed.items() if self.withdrawn.get(t, -1) < placed]
        elif self.parameter_expected is not None:
            ids = self.parameter_expected
        else:
            ids = self.structure.tile_ids
        return sorted(set(ids) & set(self.structure.tiles))

    def _update_expected(self) -> None:
        """S_a changed: the next scan is inspected against the new one (the scan being inspected
        keeps the model and the fusion it started with)."""
        with self.news_lock:
            self.expected_changed = True

    def _apply_news(self) -> None:
        """Between two scans (inspection thread): what the state callbacks learnt of S_a."""
        with self.news_lock:
            changed, self.expected_changed = self.expected_changed, False
            forget, self.to_forget = self.to_forget, []
            expected, structure = (self._expected_ids(), self.structure) if changed else (None, None)
        if forget:
            self.fusion.forget(forget)  # (re)placed or given up: what was seen of them is history
        if expected is not None and structure is not None:
            self._swap_expected(structure, expected)

    def _swap_expected(self, structure: StructureModel, expected: list[int]) -> None:
        if self.pipeline is None or self.pipeline.structure is not structure:
            self.pipeline = InspectionPipeline(structure, expected, self.settings)
            self.fusion = TileFusion(self.pipeline.evidence_settings, paper_rules=self.settings.paper_rules)
        elif tuple(expected) != self.pipeline.expected_ids:
            self.fusion.forget(set(self.pipeline.expected_ids) - set(expected))
            self.pipeline.set_expected(expected)

    def _on_structure(self, msg: Structure) -> None:
        try:
            structure = structure_from_msg(msg)
        except StructureError as error:
            self._diagnose(DiagnosticStatus.ERROR, f"ignored /structure: {error}")
            return
        with self.news_lock:
            self.structure = structure
            self.expected_changed = True
        self.get_logger().info(f"structure '{structure.name}' with {len(structure)} tiles")

    def _on_report(self, msg: PlacementReport) -> None:
        stamp, tile_id = stamp_to_nanoseconds(msg.header.stamp), int(msg.tile_id)
        with self.news_lock:
            self.reports_seen = True
            if msg.outcome == PlacementReport.OUTCOME_PLACED:
                self.placed[tile_id] = max(stamp, self.withdrawn.get(tile_id, -1) + 1)
            else:
                self.placed.pop(tile_id, None)
            self.to_forget.append(tile_id)
            self.expected_changed = True

    def _on_robot_status(self, msg: RobotStatus) -> None:
        with self.news_lock:
            self.in_hand.heard(msg.state == RobotStatus.PLACING, int(msg.current_tile),
                               stamp_to_nanoseconds(msg.header.stamp))

    def _s_a_at(self, stamp: int) -> tuple[list[int], frozenset[int]]:
        """S_a for a scan taken at `stamp` (ns), and the tiles in hand then (`tiles_in_hand`): a tile
        a robot was placing may lie there already, and one reported placed after the scan was taken
        may not have been there yet (an inspection takes a second or more on a loaded host; two VI
        robots' scans of a tile that landed just after them had it auctioned as missing)."""
        with self.news_lock:
            self.in_hand.forget_before(stamp)
            expected = self._expected_ids() or []
            later = {t for t in expected if self.placed.get(t, -1) > stamp}
            return [t for t in expected if t not in later], self.in_hand.at(stamp, expected) | later

    def _on_announcement(self, msg: AuctionAnnouncement) -> None:
        if msg.reason == AuctionAnnouncement.REASON_MISPLACED:
            # a repair: the wrong tile lies there until its robot reports it taken off, and it still
            # hides what it hid (withdrawn, its supports' faces under it looked misplaced)
            return
        tile_id = int(msg.tile_id)
        with self.news_lock:
            self.withdrawn[tile_id] = max(stamp_to_nanoseconds(msg.header.stamp), self.placed.get(tile_id, -1))
            self.expected_changed = True

    # -- scans ------------------------------------------------------------------------------------
    def _match_sensor_publishers(self) -> None:
        """(Re)subscribe the sensor streams with the reliability that works with their publishers.

        Sensor data is best effort, but Fast DDS drops every fragmented sample (a 640x480 cloud is
        3.7 MB) on a best-effort reader, and small samples can drown in a cloud's fragments: with
        `auto`, a stream is read reliably whenever every publisher offers it, best effort
        otherwise (which still matches any publisher).
        """
        for topic, kind, callback, depth in (
            ("camera/depth/points", PointCloud2, self._on_cloud, 1),
            ("overhead_pose", PoseStamped, self._on_pose, 50),
        ):
            choice = self.settings.sensor_reliability
            if choice == "reliable":
                wanted = ReliabilityPolicy.RELIABLE
            elif choice == "best_effort":
                wanted = ReliabilityPolicy.BEST_EFFORT
            else:
                publishers = self.get_publishers_info_by_topic(self.resolve_topic_name(topic))
                reliable = bool(publishers) and all(
                    p.qos_profile.reliability == ReliabilityPolicy.RELIABLE for p in publishers
                )
                wanted = ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT
            current = self.sensor_subscriptions.get(topic)
            if current is not None and current[1] == wanted:
                continue
            if current is not None:
                self.destroy_subscription(current[0])
            qos = sensor_stream(depth, wanted)
            # no QoS event handlers: rclpy's executor fails on the handler of a subscription destroyed
            # while it builds its wait set ("destruction was requested"), and this one is replaced
            subscription = self.create_subscription(
                kind, topic, callback, qos,
                event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
            )
            self.sensor_subscriptions[topic] = (subscription, wanted)

    def _on_pose(self, msg: PoseStamped) -> None:
        p, q = msg.pose.position, msg.pose.orientation
        try:
            pose = OverheadPose.from_quaternion(p.x, p.y, q.x, q.y, q.z, q.w)
        except ValueError:
            self._diagnose(DiagnosticStatus.WARN, "ignored an overhead pose with a zero quaternion")
            return
        self.poses.add(stamp_to_nanoseconds(msg.header.stamp), pose)
        self._wake_inspection()

    def _on_cloud(self, msg: PointCloud2) -> None:
        with self.wake:
            dropped, self.pending = self.pending, msg
            self.pending_since = time.monotonic()
        self._wake_inspection()
        if dropped is not None:
            reason = "dropped a scan: a newer one arrived before its overhead pose"
            self._unclassified(dropped, DiagnosticStatus.WARN, reason)

    def _wake_inspection(self) -> None:
        with self.wake:
            self.woken = True
            self.wake.notify()

    def stop_inspecting(self) -> None:
        """End the inspection at its next stage and take no more scans (before the node is destroyed)."""
        with self.wake:
            self.closing = True
            self.wake.notify()
        if self.inspection_thread.is_alive():
            self.inspection_thread.join()

    def _inspect_scans(self) -> None:
        """The inspection thread: a scan is inspected as soon as its overhead pose is here. Its own
        thread, woken by the callbacks, not an executor's timer: in wall time whatever the
        simulated clock does, and no polling that takes the interpreter from the inspection."""
        while True:
            with self.wake:
                # a scan waiting for a nearer overhead pose is looked at again every 20 ms
                self.wake.wait_for(lambda: self.woken or self.closing, timeout=0.02)
                self.woken = False
                if self.closing:
                    return
            if self.context.ok():
                self._apply_news()
                self._process_pending_scan()

    def _process_pending_scan(self) -> None:
        with self.wake:
            msg, waited = self.pending, time.monotonic() - self.pending_since
        if msg is None:
            return
        stamp = stamp_to_nanoseconds(msg.header.stamp)
        match = self.poses.nearest(stamp, int(self.settings.pose_tolerance * 1e9))
        latest = self.poses.latest_stamp
        near_enough = match is not None and match[1] <= int(self.settings.pose_near_enough * 1e9)
        if match is None or (
            not near_enough and latest is not None and latest < stamp and waited < self.settings.pose_tolerance
        ):
            # a nearer pose may still be on its way: wait for one newer than the scan, but not long
            if waited < max(1.0, 2 * self.settings.pose_tolerance):
                return
            if self._take_pending(msg):
                reason = f"dropped a scan: no overhead pose within {self.settings.pose_tolerance:g} s of it"
                self._unclassified(msg, DiagnosticStatus.WARN, reason)
            return
        if self.team.behind(stamp, self.other_robots.subscriptions) and waited < self.settings.robot_pose_tolerance:
            return  # a robot left unmasked beside a tile makes the tile look moved: wait for its pose
        if self._take_pending(msg):
            robots = self.team.at(stamp, int(self.settings.robot_pose_tolerance * 1e9))
            if len(robots) < len(self.team.buffers):
                self.get_logger().warning(
                    f"{len(self.team.buffers) - len(robots)} robot(s) without an overhead pose within "
                    f"{self.settings.robot_pose_tolerance:g} s of a scan: their points are not left out",
                    throttle_duration_sec=10.0)
            self._inspect(msg, match[0], robots)

    def _take_pending(self, msg: PointCloud2) -> bool:
        """Takes `msg` off `pending`, unless a newer scan replaced it meanwhile."""
        with self.wake:
            if self.pending is not msg:
                return False
            self.pending = None
            return True

    def _inspect(self, msg: PointCloud2, overhead: OverheadPose, robots: list[OverheadPose]) -> None:
        if msg.header.frame_id != OPTICAL_FRAME:
            reason = f"dropped a scan in frame '{msg.header.frame_id}', expected '{OPTICAL_FRAME}'"
            self._unclassified(msg, DiagnosticStatus.ERROR, reason)
            return
        if self.pipeline is None:
            reason = "dropped a scan: no structure yet (structure_file or /structure)"
            self._unclassified(msg, DiagnosticStatus.WARN, reason)
            return
        try:
            cloud = cloud_from_msg(msg)
        except CloudError as error:
            self._unclassified(msg, DiagnosticStatus.ERROR, f"dropped a scan: {error}")
            return
        expected, in_hand = self._s_a_at(stamp_to_nanoseconds(msg.header.stamp))
        if tuple(expected) != self.pipeline.expected_ids or in_hand != self.pipeline.in_hand:
            self.pipeline.set_expected(expected, in_hand)
        try:
            result = self.pipeline.inspect(cloud, overhead, robots, stop_requested=lambda: self.closing)
        except InspectionStoppedError:
            return
        except Exception as error:
            self.get_logger().error(f"inspection of a scan failed unexpectedly: {error!r}")
            self._unclassified(msg, DiagnosticStatus.ERROR, f"inspection failed unexpectedly: {error!r}")
            return
        if not result.ok:
            self._unclassified(msg, DiagnosticStatus.WARN, f"no tile states for this scan: {result.reason}", result)
            return
        if self.settings.fuse_scans:
            result = fuse_scan(self.fusion, result)
        if not self.context.ok():  # shut down while this scan was inspected
            return
        self.states_pub.publish(self._states_msg(msg, result))
        self.markers_pub.publish(self._markers_msg(msg, result))
        message = f"classified {len(result.tiles)} tiles ({len(robots)} other robots in the scene)"
        self._diagnose(DiagnosticStatus.OK, message, result)

    def _unclassified(
        self, scan: PointCloud2, level: bytes | int, message: str, result: ScanResult | None = None
    ) -> None:
        """Tell /tile_states (no states, the reason) and /diagnostics that a scan gave no states."""
        if self.context.ok():
            self.states_pub.publish(
                TileStateArray(header=Header(stamp=scan.header.stamp, frame_id="map"), problem=message,
                               robot_name=self.robot_name)
            )
        self._diagnose(level, message, result)

    # -- messages out -----------------------------------------------------------------------------
    def _states_msg(self, scan: PointCloud2, result: ScanResult) -> TileStateArray:
        out = TileStateArray()
        out.header.stamp = scan.header.stamp
        out.header.frame_id = "map"
        out.robot_name = self.robot_name
        out.scan_count = result.scan_count
        if result.camera_pose is not None:
            pose = result.camera_pose
            out.camera_pose.position.x, out.camera_pose.position.y, out.camera_pose.position.z = (
                float(v) for v in pose[:3, 3]
            )
            q = quaternion_from_rotation(pose[:3, :3])
            o = out.camera_pose.orientation
            o.x, o.y, o.z, o.w = q
        out.alignment_rms = float(result.alignment_rms) if np.isfinite(result.alignment_rms) else 0.0
        for tile in result.tiles:
            out.states.append(
                TileState(
                    tile_id=tile.tile_id,
                    state=int(tile.state),
                    physical_support=tile.physical,
                    virtual_support=tile.virtual,
                    support_ratio=float(tile.ratio),
                    residual=float(tile.residual),
                    see_through_support=tile.see_through,
                    occluded_support=tile.in_front,
                    scan_count=tile.scans,
                    offset_x=float(tile.offset[0]),
                    offset_y=float(tile.offset[1]),
                    offset_yaw=float(tile.offset[2]),
                    seen_type=tile.seen_type,
                )
            )
        return out

    def _markers_msg(self, scan: PointCloud2, result: ScanResult) -> MarkerArray:
        markers = MarkerArray()
        clear = Marker(action=Marker.DELETEALL)
        clear.header.frame_id = "map"
        clear.ns = "tiles"
        markers.markers.append(clear)
        assert self.pipeline is not None  # the structure this scan was inspected against
        for tile in result.tiles:
            placed = self.pipeline.structure.tiles[tile.tile_id]
            markers.markers.append(self._tile_marker(scan, placed, "tiles", COLOURS[tile.state]))
            if tile.state == State.MISPLACED:  # and where the scan says it really is
                where = moved_tile(placed, tile.offset)
                markers.markers.append(self._tile_marker(scan, where, "measured", MEASURED_COLOUR))
        return markers

    @staticmethod
    def _tile_marker(
        scan: PointCloud2, tile: PlacedTile, namespace: str, colour: tuple[float, ...]
    ) -> Marker:
        triangles, _ = tile.triangles
        marker = Marker(type=Marker.TRIANGLE_LIST, action=Marker.ADD, id=tile.tile_id, ns=namespace)
        marker.header.frame_id = "map"
        marker.header.stamp = scan.header.stamp
        marker.pose.orientation.w = 1.0
        marker.scale.x = marker.scale.y = marker.scale.z = 1.0
        r, g, b, a = colour
        marker.color = ColorRGBA(r=r, g=g, b=b, a=a)
        corners = tile.vertices[triangles.reshape(-1)]
        marker.points = [Point(x=float(x), y=float(y), z=float(z)) for x, y, z in corners]
        return marker

    def _diagnose(self, level: bytes | int, message: str, result: ScanResult | None = None) -> None:
        status = DiagnosticStatus(
            name="vi_node: inspection", hardware_id=self.get_namespace(), message=message
        )
        status.level = level if isinstance(level, bytes) else bytes([level])
        if result is not None:
            status.values = [
                KeyValue(key=f"{stage} ms", value=f"{seconds * 1e3:.1f}")
                for stage, seconds in result.timings.items()
            ]
            status.values.append(KeyValue(key="candidates", value=str(result.candidates)))
            status.values.extend(KeyValue(key="note", value=note) for note in result.notes)
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics_pub.publish(array)
        if status.level != DiagnosticStatus.OK:
            self.get_logger().warning(message, throttle_duration_sec=2.0)


def main(args: list[str] | None = None) -> int:
    # one executor thread: its callbacks are all short (the inspection has its own thread), and a
    # MultiThreadedExecutor's idle threads spin on the interpreter lock, which tripled the wall time
    # of each scan's inspection in the team (pipeline median 164 -> 57 ms, paper_14)
    return run_node(ViNode, (StartupError,), args=args, on_shutdown=ViNode.stop_inspecting)


if __name__ == "__main__":
    sys.exit(main())
