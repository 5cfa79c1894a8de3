"""`ros2 run vi_node classify` on recorded bags, as users run it (paper mode)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from vi_helpers import REPO, SCANS, STRUCTURES, ros2_run

from tiling_sim.scan_bag import ScanBagWriter, read_truth
from vi_node.classify_bag import ScanInspector, read_recording
from vi_node.inspection_settings import InspectionSettings

PAPER = str(STRUCTURES / "paper_14.yaml")
STATES = {"present", "missing", "occluded"}


def classify(*args: str) -> tuple[list[dict], str, int]:  # type: ignore[type-arg]
    result = ros2_run("vi_node", "classify", "--structure", PAPER, *args)
    lines = [json.loads(line) for line in result.stdout.splitlines() if line.strip()]
    return lines, result.stderr, result.returncode


def test_paper_mode_one_json_object_per_scan_with_the_contract_keys() -> None:
    lines, stderr, code = classify("--bag", str(SCANS / "paper_vga"), "--mode", "paper", "--no-fuse")
    assert code == 0, stderr
    truth = read_truth(SCANS / "paper_vga")
    assert [line["stamp"] for line in lines] == [s["stamp_ns"] / 1e9 for s in truth["scans"]]
    for line in lines:
        assert set(line["tiles"]) == {str(t) for t in truth["expected"]}
        for entry in line["tiles"].values():
            assert entry["state"] in STATES
            assert isinstance(entry["physical"], int) and isinstance(entry["virtual"], int)
        for removed in truth["removed"]:  # the square and the triangle, in plain view
            assert line["tiles"][str(removed)]["state"] == "missing"
        for tile in truth["present"]:
            assert line["tiles"][str(tile)]["state"] != "missing" or tile == 5  # 5 lies under removed 10
        assert line["tiles"]["3"]["state"] == "occluded"
        assert line["scan_count"] == 1


def test_default_mode_fuses_the_scans_and_finds_every_removed_tile() -> None:
    truth = read_truth(SCANS / "paper_qvga")
    lines, stderr, code = classify("--bag", str(SCANS / "paper_qvga"))
    assert code == 0, stderr
    assert [line["scan_count"] for line in lines] == [1, 2, 3, 4]
    for line in lines:
        assert set(line["tiles"]) == {str(t) for t in truth["expected"]}
        for tile_id, entry in line["tiles"].items():
            assert entry["state"] in STATES
            assert {"see_through", "in_front", "no_return", "judged"} <= set(entry) or entry["virtual"] == 0
            if int(tile_id) in truth["removed"]:
                assert entry["state"] == "missing", (tile_id, entry)  # 320x240, another robot in the scene
            else:
                assert entry["state"] != "missing", (tile_id, entry)
    final = lines[-1]["tiles"]
    assert final["2"]["state"] == "present" and final["2"].get("scans", 0) >= 2  # resolved once seen
    single, _, _ = classify("--bag", str(SCANS / "paper_qvga"), "--no-fuse")
    assert all(line["scan_count"] == 1 for line in single)
    assert single[0]["tiles"]["2"]["state"] == "occluded"  # the first view does not see it


def test_inspecting_in_several_processes_gives_the_same_lines_in_bag_order() -> None:
    serial, stderr, code = classify("--bag", str(SCANS / "paper_qvga"), "--no-fuse", "--jobs", "1")
    assert code == 0, stderr
    parallel, stderr, code = classify("--bag", str(SCANS / "paper_qvga"), "--no-fuse", "--jobs", "3")
    assert code == 0, stderr
    assert parallel == serial and len(serial) == 4
    _, stderr, code = classify("--bag", str(SCANS / "paper_qvga"), "--jobs", "0")
    assert code == 2 and stderr.count("\n") == 1 and "Traceback" not in stderr


def test_a_misplaced_tile_is_reported_with_its_offset() -> None:
    truth = read_truth(SCANS / "paper_misplaced_qvga")
    lines, stderr, code = classify("--bag", str(SCANS / "paper_misplaced_qvga"))
    assert code == 0, stderr
    moved = truth["misplaced"][0]
    true_yaw = truth["misplaced_pose"][str(moved)]["yaw"]
    entry = lines[-1]["tiles"][str(moved)]
    assert entry["state"] == "misplaced"
    assert abs(entry["offset"][2] - true_yaw) < 0.05 and abs(entry["offset"][0]) < 0.01
    for line in lines:
        assert sum(e["state"] == "misplaced" for e in line["tiles"].values()) <= 1
        assert line["tiles"]["13"]["state"] == "missing"


def test_expected_tiles_and_parameter_file(tmp_path: Path) -> None:
    lines, stderr, code = classify("--bag", str(SCANS / "paper_qvga"), "--expected", "1,2,3,6,7")
    assert code == 0, stderr
    assert all(set(line["tiles"]) == {"1", "2", "3", "6", "7"} for line in lines if not line.get("error"))
    params = tmp_path / "params.yaml"
    params.write_text("/**:\n  ros__parameters:\n    min_support: 30\n")
    strict, _, _ = classify("--bag", str(SCANS / "paper_qvga"), "--mode", "paper", "--no-fuse")
    loose, _, _ = classify(
        "--bag", str(SCANS / "paper_qvga"), "--params", str(params), "--mode", "paper", "--no-fuse"
    )
    occluded = lambda lines: sum(e["state"] == "occluded" for line in lines for e in line["tiles"].values())  # noqa: E731
    assert occluded(loose) < occluded(strict)  # 320x240 scans: the 100-point threshold hides small tiles


def test_wrong_camera_mount_gives_errors_not_wrong_states() -> None:
    lines, stderr, code = classify("--bag", str(SCANS / "paper_vga"), "--camera-xyz", "0.08,0.6,0.55")
    assert code == 0
    assert len(lines) == 2 and all(
        line["tiles"] == {} and ("alignment failed" in line["error"] or "S_a not in view" in line["error"])
        for line in lines
    )
    assert len(stderr.strip().splitlines()) == 2 and "Traceback" not in stderr


def one_line_error(args: list[str], code: int, text: str) -> None:
    lines, stderr, status = classify(*args)
    assert status == code and lines == []
    assert len(stderr.strip().splitlines()) == 1 and text in stderr and "Traceback" not in stderr


def test_bad_arguments_files_and_bags(tmp_path: Path) -> None:
    one_line_error(["--bag", str(tmp_path / "none")], 1, "not a rosbag2 folder")
    one_line_error(["--bag", str(SCANS / "paper_vga"), "--intrinsics", "1,2,3"], 2, "--intrinsics needs 4")
    one_line_error(["--bag", str(SCANS / "paper_vga"), "--expected", "3,99"], 2, "tiles 99 are not in")
    one_line_error(["--bag", str(SCANS / "paper_vga"), "--mode", "fast"], 2, "invalid choice")
    bad_structure = tmp_path / "bad.yaml"
    bad_structure.write_text("name: x\n")
    result = ros2_run(
        "vi_node", "classify", "--structure", str(bad_structure), "--bag", str(SCANS / "paper_vga")
    )
    assert result.returncode == 2 and result.stderr.count("\n") == 1 and str(bad_structure) in result.stderr
    (tmp_path / "empty").mkdir()
    one_line_error(["--bag", str(tmp_path / "empty")], 1, "cannot open the bag")
    no_cloud = tmp_path / "no_cloud"
    with ScanBagWriter(no_cloud) as bag:
        bag.write_pose(1, 0.0, 0.0, 0.0)
    # the writer always declares the cloud topic: drop it by rewriting the bag with poses only
    store = get_typestore(Stores.ROS2_JAZZY)
    only_poses = tmp_path / "only_poses"
    with Writer(only_poses, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        writer.add_connection("/vi/overhead_pose", "geometry_msgs/msg/PoseStamped", typestore=store)
    one_line_error(["--bag", str(only_poses)], 1, "no /vi/camera/depth/points topic")


def test_bad_scans_in_a_bag_are_reported_and_skipped(tmp_path: Path) -> None:
    path = tmp_path / "bag"
    good = read_vga_cloud()
    with ScanBagWriter(path) as bag:
        view = read_truth(SCANS / "paper_vga")["scans"][0]["view"]
        bag.write_pose(10**9, *view["overhead"])
        bag.write_scan(10**9, np.full_like(good, np.nan))  # nothing but NaN
        bag.write_scan(10**9 + 10**6, good, frame_id="base_link")  # wrong frame
        bag.write_scan(10**9 + 2 * 10**6, good)  # fine
        bag.write_scan(5 * 10**9, good)  # no overhead pose near it
    lines, stderr, code = classify("--bag", str(path))
    assert code == 0
    assert [bool(line["tiles"]) for line in lines] == [False, False, True, False]
    assert "no valid points" in lines[0]["error"]
    assert "frame is 'base_link'" in lines[1]["error"]
    assert "no overhead pose within" in lines[3]["error"]
    assert len(stderr.strip().splitlines()) == 3


def read_vga_cloud() -> np.ndarray:
    from vi_node.classify_bag import read_recording

    return next(iter(read_recording(SCANS / "paper_vga").scans)).cloud  # type: ignore[return-value]


def test_reads_sqlite3_bags_with_a_driver_style_cloud_layout(tmp_path: Path) -> None:
    """As `ros2 bag record` on Humble writes them: SQLite3 storage, 16-byte points (x y z + pad)."""
    cloud = read_vga_cloud()
    view = read_truth(SCANS / "paper_vga")["scans"][0]["view"]
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    padded = np.zeros((480, 640, 4), dtype=np.float32)
    padded[..., :3] = cloud
    stamp = types["builtin_interfaces/msg/Time"](sec=7, nanosec=0)
    scan = types["sensor_msgs/msg/PointCloud2"](
        header=types["std_msgs/msg/Header"](stamp=stamp, frame_id="camera_depth_optical_frame"),
        height=480,
        width=640,
        is_bigendian=False,
        point_step=16,
        row_step=16 * 640,
        is_dense=False,
        fields=[
            types["sensor_msgs/msg/PointField"](name=n, offset=4 * k, datatype=7, count=1)
            for k, n in enumerate("xyz")
        ],
        data=padded.reshape(-1).view(np.uint8),
    )
    x, y, yaw = view["overhead"]
    pose = types["geometry_msgs/msg/PoseStamped"](
        header=types["std_msgs/msg/Header"](stamp=stamp, frame_id="map"),
        pose=types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=types["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
            ),
        ),
    )
    path = tmp_path / "humble_bag"
    with Writer(path, version=8, storage_plugin=StoragePlugin.SQLITE3) as writer:
        c = writer.add_connection("/vi/camera/depth/points", "sensor_msgs/msg/PointCloud2", typestore=store)
        p = writer.add_connection("/vi/overhead_pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        writer.write(p, 7 * 10**9, store.serialize_cdr(pose, "geometry_msgs/msg/PoseStamped"))
        writer.write(c, 7 * 10**9 + 1, store.serialize_cdr(scan, "sensor_msgs/msg/PointCloud2"))
    lines, stderr, code = classify("--bag", str(path))
    assert code == 0, stderr
    assert len(lines) == 1 and lines[0]["stamp"] == 7.0
    assert lines[0]["tiles"]["13"]["state"] == "missing" and lines[0]["tiles"]["11"]["state"] == "present"


def test_repository_paths_exist() -> None:
    assert (REPO / "install" / "vi_node" / "lib" / "vi_node" / "classify").exists()


def test_scans_are_shared_between_this_process_and_its_workers_in_bag_order() -> None:
    """Once the worker is up, scans go to it while this process inspects the others; the results
    are the same scan for scan as one process alone gives, in the bag's order."""
    structure = str(REPO / "config" / "structures" / "paper_14.yaml")
    settings = InspectionSettings()
    with ScanInspector(structure, None, settings, jobs=1) as alone:
        expected = [(scan.stamp_ns, result.by_id() if result else None, error)
                    for scan, result, error in alone.judge(read_recording(SCANS / "paper_vga"))]
    with ScanInspector(structure, None, settings, jobs=2) as shared:
        assert shared.workers_up.result(timeout=60)
        got = [(scan.stamp_ns, result.by_id() if result else None, error)
               for scan, result, error in shared.judge(read_recording(SCANS / "paper_vga"))]
        assert shared.handed_out >= 1
    assert [g[0] for g in got] == sorted(g[0] for g in got)
    assert [(s, {k: t.state for k, t in r.items()} if r else None, e) for s, r, e in got] == \
        [(s, {k: t.state for k, t in r.items()} if r else None, e) for s, r, e in expected]
