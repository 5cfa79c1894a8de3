"""`ros2 run vi_node classify`: the inspection pipeline on a recorded rosbag2, offline.

    ros2 run vi_node classify --structure FILE --bag DIR [--expected all|ID,ID,...] [--params FILE]
        [--camera-xyz X,Y,Z] [--camera-rpy R,P,Y] [--intrinsics FX,FY,CX,CY] [--mode default|paper]
        [--no-fuse] [--jobs N]

Reads `/vi/camera/depth/points` (sensor_msgs/PointCloud2) and `/vi/overhead_pose`
(geometry_msgs/PoseStamped) from a rosbag2 folder (MCAP or SQLite, as `ros2 bag record` or
`tiling_sim`'s writer made it), and the other robots' `/<robot>/overhead_pose` where the bag holds
them (their points are left out, as the node does), pairs every scan with the overhead pose nearest
in time and prints
one JSON object per scan, in the bag's order (DESIGN.md, inspection contract):
{"stamp": S, "tiles": {"ID": {"state": "present"|"missing"|"occluded", "physical": N, "virtual": N}}}.
States are fused over the bag's scans as the node fuses them (`fuse_scans`; `--no-fuse`: every
scan on its own). Extra keys: "scan_count", "alignment_rms", "camera_position" per scan; per tile
"ratio", "residual", in the default mode the pixel evidence "see_through", "blank" (against the
tile), "ambiguous", "in_front", "no_return" (saying nothing), "judged" and, for a tile found
misplaced, state "misplaced" and "offset" [x, y, yaw] (m, rad).
A scan that cannot be classified prints its stamp, empty "tiles" and an "error", plus one line on
stderr. Bad arguments, parameters or structure: one line on stderr, exit status 2; a bag that
cannot be read: one line, exit status 1.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import os
import signal
import sys
from collections import deque
from collections.abc import Callable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.interrupts import postponed_signals
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from vi_node.classify import TileState
from vi_node.fusion import TileFusion, fuse_scan
from vi_node.inspection_settings import (
    MODES,
    InspectionSettings,
    SettingsError,
    load_settings,
    parse_tile_ids,
)
from vi_node.pipeline import InspectionPipeline
from vi_node.point_cloud import CloudError, cloud_from_msg
from vi_node.pose_matching import PoseBuffer, TeamPoses
from vi_node.pose_prior import OverheadPose
from vi_node.scan_result import ScanResult

CLOUD_TOPIC = "/vi/camera/depth/points"
POSE_TOPIC = "/vi/overhead_pose"
OPTICAL_FRAME = "camera_depth_optical_frame"


class BagError(RuntimeError):
    """A bag that cannot be read as an inspection recording."""


@dataclass
class RecordedScan:
    stamp_ns: int
    frame_id: str
    cloud: NDArray[np.float32] | None  # None when the message could not be read
    problem: str = ""


def _stamp_ns(header: Any, fallback: int) -> int:
    stamp = int(header.stamp.sec) * 10**9 + int(header.stamp.nanosec)
    return stamp if stamp > 0 else fallback


@dataclass
class Recording:
    """The overhead poses of a bag (the VI robot's and the other robots'), and its scans one by one."""

    poses: PoseBuffer
    team: TeamPoses
    scans: Iterator[RecordedScan]


def read_recording(bag: str | Path, cloud_topic: str = CLOUD_TOPIC, pose_topic: str = POSE_TOPIC) -> Recording:
    """All overhead poses of the bag, and its scans one by one (in the bag's order)."""
    from rosbags.rosbag2 import Reader, ReaderError
    from rosbags.typesys import Stores, get_typestore

    path = Path(bag)
    if not path.is_dir():
        raise BagError(f"{path}: not a rosbag2 folder")
    typestore = get_typestore(Stores.ROS2_JAZZY)
    try:
        reader = Reader(path)
        reader.open()
    except (ReaderError, OSError) as error:
        raise BagError(f"{path}: cannot open the bag: {error}") from None
    topics = {c.topic: c for c in reader.connections}
    if cloud_topic not in topics:
        reader.close()
        raise BagError(f"{path}: no {cloud_topic} topic (topics: {', '.join(sorted(topics)) or 'none'})")
    poses, team = PoseBuffer(capacity=10**7), TeamPoses(capacity=10**7)
    pose_connections = [
        c
        for c in reader.connections
        if c.topic == pose_topic or (c.topic.endswith("/overhead_pose") and c.topic.count("/") == 2)
    ]
    try:
        for connection, timestamp, raw in reader.messages(connections=pose_connections):
            msg = typestore.deserialize_cdr(raw, connection.msgtype)
            p, q = msg.pose.position, msg.pose.orientation
            try:
                pose = OverheadPose.from_quaternion(p.x, p.y, q.x, q.y, q.z, q.w)
            except ValueError:
                continue  # a zero quaternion: not a pose
            stamp = _stamp_ns(msg.header, timestamp)
            if connection.topic == pose_topic:
                poses.add(stamp, pose)
            else:
                team.add(connection.topic.split("/")[1], stamp, pose)
    except ReaderError as error:
        reader.close()
        raise BagError(f"{path}: cannot read the bag: {error}") from None

    def scans() -> Iterator[RecordedScan]:
        try:
            cloud_connections = [c for c in reader.connections if c.topic == cloud_topic]
            for connection, timestamp, raw in reader.messages(connections=cloud_connections):
                try:
                    msg = typestore.deserialize_cdr(raw, connection.msgtype)
                except Exception as error:
                    yield RecordedScan(timestamp, "", None, f"unreadable message: {error}")
                    continue
                stamp = _stamp_ns(msg.header, timestamp)
                try:
                    cloud = cloud_from_msg(msg)
                except CloudError as error:
                    yield RecordedScan(stamp, msg.header.frame_id, None, f"bad cloud: {error}")
                    continue
                yield RecordedScan(stamp, msg.header.frame_id, cloud)
        except ReaderError as error:
            raise BagError(f"{path}: cannot read the bag: {error}") from None
        finally:
            reader.close()

    return Recording(poses, team, scans())


def result_json(stamp_ns: int, result: ScanResult | None, error: str = "", pixels: bool = False) -> dict[str, Any]:
    """The contract's JSON object for one scan (extra keys beyond the contract's are allowed);
    `pixels`: with the pixel evidence of the default mode."""
    out: dict[str, Any] = {"stamp": stamp_ns / 1e9, "tiles": {}}
    if result is None or not result.ok:
        out["error"] = error or (result.reason if result else "not classified")
        return out
    for tile in result.tiles:
        entry: dict[str, Any] = {
            "state": tile.state.label,
            "physical": tile.physical,
            "virtual": tile.virtual,
            "ratio": round(tile.ratio, 3),
            "residual": round(tile.residual, 4),
        }
        if pixels:
            entry.update(
                see_through=tile.see_through,
                blank=tile.blank,
                ambiguous=tile.ambiguous,
                in_front=tile.in_front,
                no_return=tile.no_return,
                judged=tile.judged,
            )
        if result.scan_count > 1:
            entry["scans"] = tile.scans
        if tile.state == TileState.MISPLACED:
            entry["offset"] = [round(tile.offset[0], 4), round(tile.offset[1], 4), round(tile.offset[2], 4)]
            if tile.seen_type:
                entry["seen_type"] = tile.seen_type
        out["tiles"][str(tile.tile_id)] = entry
    out["scan_count"] = result.scan_count
    out["alignment_rms"] = round(result.alignment_rms, 5) if math.isfinite(result.alignment_rms) else None
    if result.camera_pose is not None:
        out["camera_position"] = [round(float(v), 4) for v in result.camera_pose[:3, 3]]
    return out


def _numbers(text: str, count: int, name: str) -> list[float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{name} needs {count} comma-separated numbers, got '{text}'"
        ) from None
    if len(values) != count or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{name} needs {count} comma-separated numbers, got '{text}'")
    return values


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # type: ignore[override]
        """One line, not argparse's usage block: `error: ...`, exit status 2."""
        print(f"error: {message}", file=sys.stderr)
        raise SystemExit(2)



def _at_least_one(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value

def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="ros2 run vi_node classify",
        description="Classify every expected tile in every scan of a recorded rosbag2 (JSON lines out).",
    )
    parser.add_argument("--structure", required=True, help="structure file (config/structures/*.yaml)")
    parser.add_argument(
        "--bag", required=True, help="rosbag2 folder with /vi/camera/depth/points and /vi/overhead_pose"
    )
    parser.add_argument(
        "--expected", default=None, help="S_a: 'all' or comma-separated tile ids (default: the parameters')"
    )
    parser.add_argument(
        "--params",
        default=None,
        help="parameter file in the node's format (default: built-in = config/vi_node.yaml)",
    )
    parser.add_argument(
        "--camera-xyz",
        type=lambda t: _numbers(t, 3, "--camera-xyz"),
        help="camera_link position in base_link (m)",
    )
    parser.add_argument(
        "--camera-rpy",
        type=lambda t: _numbers(t, 3, "--camera-rpy"),
        help="camera_link roll,pitch,yaw in base_link (rad)",
    )
    parser.add_argument(
        "--intrinsics",
        type=lambda t: _numbers(t, 4, "--intrinsics"),
        help="fx,fy,cx,cy (px) at intrinsics_size",
    )
    parser.add_argument(
        "--no-fuse",
        action="store_true",
        help="print every scan's own states (default: fused over the bag's scans, as the node publishes)",
    )
    parser.add_argument(
        "--jobs",
        type=_at_least_one,
        default=min(2, len(os.sched_getaffinity(0))),
        help="processes inspecting scans side by side, this one included (default: this machine's cores, at most 2)",
    )
    parser.add_argument(
        "--mode",
        choices=MODES,
        default=None,
        help="classification mode (default: the parameters')",
    )
    return parser


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return _run(args)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return 0


def _run(args: argparse.Namespace) -> int:
    try:
        settings = load_settings(args.params) if args.params else InspectionSettings()
        overrides: dict[str, Any] = {}
        if args.camera_xyz:
            overrides["camera_xyz"] = args.camera_xyz
        if args.camera_rpy:
            overrides["camera_rpy"] = args.camera_rpy
        if args.intrinsics:
            overrides["intrinsics"] = args.intrinsics
        if args.mode:
            overrides["mode"] = args.mode
        if args.expected is not None:
            overrides["expected_tiles"] = args.expected
        settings = settings.with_values(overrides, "command line")
    except SettingsError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    try:
        structure = load_structure(args.structure)
    except StructureError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    expected: list[int] | None = None
    if settings.expected_tiles.strip().lower() != "all":
        expected = parse_tile_ids(settings.expected_tiles)
        unknown = sorted(set(expected) - set(structure.tiles))
        if unknown:
            print(
                f"error: --expected: tiles {', '.join(map(str, unknown))} are not in {args.structure}",
                file=sys.stderr,
            )
            return 2
    fusion = TileFusion(settings.evidence(), paper_rules=settings.paper_rules)
    fuse = settings.fuse_scans and not args.no_fuse
    try:
        with ScanInspector(args.structure, expected, settings, args.jobs) as inspector:
            for scan, result, error in inspector.judge(read_recording(args.bag)):
                if result is not None and fuse:
                    result = fuse_scan(fusion, result)
                if error:
                    print(f"scan at {scan.stamp_ns / 1e9:.3f} s: {error}", file=sys.stderr)
                line = result_json(scan.stamp_ns, result, error, pixels=not settings.paper_rules)
                print(json.dumps(line), flush=True)
    except BagError as error:
        print(f"error: {error}", file=sys.stderr)
        return 1
    return 0


_worker_pipeline: InspectionPipeline | None = None


def _start_worker(structure_file: str, expected: list[int] | None, settings: InspectionSettings) -> None:
    """A worker process: its own pipeline; Ctrl-C is the parent's to handle."""
    global _worker_pipeline
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _worker_pipeline = InspectionPipeline(load_structure(structure_file), expected, settings)


def _worker_ready() -> bool:
    return _worker_pipeline is not None


def _inspect_in_worker(cloud: NDArray[np.float32], overhead: OverheadPose, robots: list[OverheadPose]) -> ScanResult:
    assert _worker_pipeline is not None
    return _worker_pipeline.inspect(cloud, overhead, robots)


class ScanInspector:
    """Inspects a recording's scans, on this process and `jobs - 1` worker processes (scans are
    independent until fused; results come back in the bag's order). This process reads and
    decodes the bag too: it inspects a scan itself only while the workers have enough queued,
    so that no core waits and one worker fewer is started (each costs ~0.5 s of imports)."""

    def __init__(self, structure_file: str, expected: list[int] | None, settings: InspectionSettings, jobs: int):
        self.settings = settings
        self.workers = max(1, jobs) - 1
        self.pool: ProcessPoolExecutor | None = None
        if self.workers:
            context = multiprocessing.get_context("spawn")  # no fork of a process with Open3D's threads
            self.pool = ProcessPoolExecutor(
                self.workers, mp_context=context, initializer=_start_worker,
                initargs=(structure_file, expected, settings),
            )
            # scans go to the workers once they are up: until then this process inspects alone
            self.workers_up = self._submit(_worker_ready)
        self.pipeline = InspectionPipeline(load_structure(structure_file), expected, settings)
        self.in_flight: list[Future[ScanResult]] = []  # scans handed to the workers, maybe done
        self.handed_out = 0  # scans the workers inspected in all

    def _submit(self, work: Callable[..., Any], *args: Any) -> Future[Any]:
        """Hand work to the pool, which may start a worker to take it. A signal arriving while a worker
        is started waits until it is: cut short, the worker's bootstrap reads half its set-up data and
        prints a traceback (EOFError) however cleanly this process stops."""
        assert self.pool is not None
        with postponed_signals():
            return self.pool.submit(work, *args)

    def __enter__(self) -> ScanInspector:
        return self

    def __exit__(self, *_exc: object) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)

    def judge(self, recording: Recording) -> Iterator[tuple[RecordedScan, ScanResult | None, str]]:
        """(scan, result or None, error) per scan, in the recording's order."""
        pending: deque[tuple[RecordedScan, Future[ScanResult] | ScanResult | None, str]] = deque()
        for scan in recording.scans:
            pending.append(self._start(scan, recording))
            while pending and _done(pending[0][1]):
                yield _finish(*pending.popleft())
        while pending:
            yield _finish(*pending.popleft())

    def _start(
        self, scan: RecordedScan, recording: Recording
    ) -> tuple[RecordedScan, Future[ScanResult] | ScanResult | None, str]:
        s = self.settings
        if scan.problem:
            return scan, None, scan.problem
        if scan.frame_id and scan.frame_id != OPTICAL_FRAME:
            return scan, None, f"cloud frame is '{scan.frame_id}', expected '{OPTICAL_FRAME}'"
        match = recording.poses.nearest(scan.stamp_ns, int(s.pose_tolerance * 1e9))
        if match is None:
            return scan, None, f"no overhead pose within {s.pose_tolerance:g} s of the scan"
        assert scan.cloud is not None
        robots = recording.team.at(scan.stamp_ns, int(s.robot_pose_tolerance * 1e9))
        self.in_flight = [job for job in self.in_flight if not job.done()]
        if self.pool is not None and self.workers_up.done() and len(self.in_flight) < 2 * self.workers:
            job = self._submit(_inspect_in_worker, scan.cloud, match[0], robots)
            self.in_flight.append(job)
            self.handed_out += 1
            return scan, job, ""
        return scan, self.pipeline.inspect(scan.cloud, match[0], robots), ""


def _done(job: Future[ScanResult] | ScanResult | None) -> bool:
    return not isinstance(job, Future) or job.done()


def _finish(
    scan: RecordedScan, job: Future[ScanResult] | ScanResult | None, error: str
) -> tuple[RecordedScan, ScanResult | None, str]:
    result = job.result() if isinstance(job, Future) else job
    if result is not None and not result.ok:
        error = result.reason
    return scan, result, error


if __name__ == "__main__":
    sys.exit(main())
