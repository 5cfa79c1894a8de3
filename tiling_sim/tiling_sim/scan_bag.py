"""Record simulated Kinect scans and overhead poses into a rosbag2 (MCAP) folder.

Writes the inspection contract's topics with standard message types, serialized as CDR by
`rosbags`, so that `ros2 bag play`, `ros2 run vi_node classify` and `ros2 run tiling_sim
replay_bag` read the result like a recording of the real robot:

- `/vi/camera/depth/points`: sensor_msgs/msg/PointCloud2, organized, x y z float32, frame
  `camera_depth_optical_frame`, NaN where there is no return;
- `/vi/overhead_pose`: geometry_msgs/msg/PoseStamped, frame `map`, x, y and yaw of `base_link`;
  `/<robot>/overhead_pose` the same of the other robots in view, where written.

MCAP chunks are zstd-compressed (rosbag2's "storage" compression, which the MCAP reader of
`ros2 bag` and `rosbags` both read): clouds full of NaN and millimetre depths shrink several-fold.
What really was in the scene goes to `truth.json` next to the bag's files (rosbag2 ignores it).
Self-contained: uses `rosbags` only, no ROS installation (the cloud is laid out by
`tiling_ros.point_clouds`, in rosbags' own message types).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
from rosbags.typesys import Stores, get_typestore

from tiling_ros.point_clouds import cloud_to_msg

CLOUD_TOPIC = "/vi/camera/depth/points"
POSE_TOPIC = "/vi/overhead_pose"
OPTICAL_FRAME = "camera_depth_optical_frame"
TRUTH_FILE = "truth.json"


class ScanBagWriter:
    """Context manager: `with ScanBagWriter(path) as bag: bag.write_pose(...); bag.write_scan(...)`."""

    def __init__(self, path: str | Path, compress: bool = True) -> None:
        self.path = Path(path)
        self.typestore = get_typestore(Stores.ROS2_JAZZY)
        self._writer = Writer(self.path, version=Writer.VERSION_LATEST, storage_plugin=StoragePlugin.MCAP)
        if compress:
            self._writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        self._truth: dict[str, Any] = {"scans": []}
        self._cloud_connection: Any = None
        self._pose_connections: dict[str, Any] = {}

    def __enter__(self) -> ScanBagWriter:
        self._writer.open()
        self._cloud_connection = self._writer.add_connection(
            CLOUD_TOPIC, "sensor_msgs/msg/PointCloud2", typestore=self.typestore
        )
        self._pose_connections["vi"] = self._writer.add_connection(
            POSE_TOPIC, "geometry_msgs/msg/PoseStamped", typestore=self.typestore
        )
        return self

    def __exit__(self, kind: object, value: object, traceback: object) -> None:
        self._writer.__exit__(kind, value, traceback)  # type: ignore[arg-type]
        if kind is None:
            (self.path / TRUTH_FILE).write_text(json.dumps(self._truth, indent=1) + "\n", encoding="utf-8")

    def set_truth(self, **entries: Any) -> None:
        """Scene-wide truth (structure file, expected, removed tiles ...) for truth.json."""
        self._truth.update(entries)

    def _header(self, stamp_ns: int, frame_id: str) -> Any:
        types = self.typestore.types
        stamp = types["builtin_interfaces/msg/Time"](sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
        return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)

    def write_pose(self, stamp_ns: int, x: float, y: float, yaw: float, robot: str = "vi") -> None:
        """An overhead pose of a robot's base_link (frame map, z = roll = pitch = 0): the VI
        robot's, or another robot's (`/<robot>/overhead_pose`)."""
        types = self.typestore.types
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=float(x), y=float(y), z=0.0),
            orientation=types["geometry_msgs/msg/Quaternion"](
                x=0.0, y=0.0, z=math.sin(yaw / 2.0), w=math.cos(yaw / 2.0)
            ),
        )
        msg = types["geometry_msgs/msg/PoseStamped"](header=self._header(stamp_ns, "map"), pose=pose)
        data = self.typestore.serialize_cdr(msg, "geometry_msgs/msg/PoseStamped")
        if robot not in self._pose_connections:
            self._pose_connections[robot] = self._writer.add_connection(
                f"/{robot}/overhead_pose", "geometry_msgs/msg/PoseStamped", typestore=self.typestore
            )
        self._writer.write(self._pose_connections[robot], stamp_ns, data)

    def write_scan(
        self,
        stamp_ns: int,
        cloud: NDArray[np.float32],
        truth: dict[str, Any] | None = None,
        frame_id: str = OPTICAL_FRAME,
    ) -> None:
        """An organized cloud (H, W, 3) float32 in the optical frame; `truth` goes to truth.json."""
        types = self.typestore.types
        msg = cloud_to_msg(
            cloud, self._header(stamp_ns, frame_id),
            cloud_type=types["sensor_msgs/msg/PointCloud2"], field_type=types["sensor_msgs/msg/PointField"],
        )
        data = self.typestore.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
        self._writer.write(self._cloud_connection, stamp_ns, data)
        self._truth["scans"].append({"stamp_ns": int(stamp_ns), **(truth or {})})


def read_truth(path: str | Path) -> dict[str, Any]:
    """The truth.json of a bag folder written by ScanBagWriter."""
    return json.loads((Path(path) / TRUTH_FILE).read_text(encoding="utf-8"))
