"""Scan bags: real rosbag2 MCAP folders with standard types, compressed chunks, and the truth."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import yaml
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from vi_helpers import SCANS

from tiling_ros.point_clouds import cloud_from_msg
from tiling_sim.scan_bag import CLOUD_TOPIC, POSE_TOPIC, ScanBagWriter, read_truth
from vi_node.classify_bag import read_recording


def test_written_bag_reads_back_with_rosbags(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    clouds = [rng.normal(size=(60, 80, 3)).astype(np.float32) for _ in range(2)]
    clouds[0][:10] = np.nan
    path = tmp_path / "bag"
    with ScanBagWriter(path) as bag:
        bag.set_truth(structure="s.yaml", removed=[3])
        for k, cloud in enumerate(clouds):
            bag.write_pose(10**9 * (k + 1), 0.5 * k, -0.25, 0.3 * k)
            bag.write_scan(10**9 * (k + 1) + 5, cloud, {"k": k})
    metadata = yaml.safe_load((path / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert metadata["storage_identifier"] == "mcap"
    assert (path / "bag.mcap").exists()
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(path) as reader:
        assert {c.topic: c.msgtype for c in reader.connections} == {
            CLOUD_TOPIC: "sensor_msgs/msg/PointCloud2",
            POSE_TOPIC: "geometry_msgs/msg/PoseStamped",
        }
        messages = [(c.topic, t, store.deserialize_cdr(raw, c.msgtype)) for c, t, raw in reader.messages()]
    assert [m[0] for m in messages] == [POSE_TOPIC, CLOUD_TOPIC, POSE_TOPIC, CLOUD_TOPIC]
    scan = messages[3][2]
    assert scan.header.frame_id == "camera_depth_optical_frame" and scan.header.stamp.nanosec == 5
    assert np.array_equal(cloud_from_msg(scan), clouds[1], equal_nan=True)
    pose = messages[2][2]
    assert pose.header.frame_id == "map" and pose.pose.position.x == 0.5
    assert abs(2 * math.atan2(pose.pose.orientation.z, pose.pose.orientation.w) - 0.3) < 1e-12
    truth = read_truth(path)
    assert truth["removed"] == [3] and [s["k"] for s in truth["scans"]] == [0, 1]


def test_chunks_are_zstd_compressed(tmp_path: Path) -> None:
    cloud = np.full((120, 160, 3), np.nan, dtype=np.float32)
    with ScanBagWriter(tmp_path / "small") as bag:
        bag.write_scan(1, cloud)
    with ScanBagWriter(tmp_path / "plain", compress=False) as bag:
        bag.write_scan(1, cloud)
    small = (tmp_path / "small" / "small.mcap").stat().st_size
    plain = (tmp_path / "plain" / "plain.mcap").stat().st_size
    assert small * 20 < plain
    assert b"zstd" in (tmp_path / "small" / "small.mcap").read_bytes()


def test_recorded_test_scans_are_small_and_complete() -> None:
    total = sum(f.stat().st_size for f in SCANS.rglob("*") if f.is_file())
    assert total < 5e6
    for name, size, count in (("paper_vga", (480, 640), 2), ("paper_qvga", (240, 320), 4)):
        recording = read_recording(SCANS / name)
        clouds = [s.cloud for s in recording.scans]
        assert len(clouds) == count and len(recording.poses) == count and not recording.team.buffers
        assert all(c is not None and c.shape == (*size, 3) for c in clouds)
        assert len(read_truth(SCANS / name)["scans"]) == count
