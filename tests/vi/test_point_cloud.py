"""PointCloud2 <-> organized numpy cloud, for rclpy and rosbags messages, any layout."""

from __future__ import annotations

import array

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore
from sensor_msgs.msg import PointCloud2, PointField

from tiling_ros.point_clouds import CloudError, cloud_bytes, cloud_from_msg


def sample_cloud(height: int = 48, width: int = 64) -> np.ndarray:
    rng = np.random.default_rng(1)
    cloud = rng.normal(size=(height, width, 3)).astype(np.float32)
    cloud[rng.random((height, width)) < 0.3] = np.nan
    return cloud


def ros_message(
    data: bytes,
    height: int,
    width: int,
    fields: list[tuple[str, int, int]],
    point_step: int,
    row_step: int,
    big_endian: bool = False,
) -> PointCloud2:
    msg = PointCloud2(
        height=height, width=width, point_step=point_step, row_step=row_step, is_bigendian=big_endian
    )
    msg.fields = [PointField(name=n, offset=o, datatype=t, count=1) for n, o, t in fields]
    msg.data = array.array("B", data)
    return msg


def test_round_trip_through_an_rclpy_message() -> None:
    cloud = sample_cloud()
    msg = ros_message(cloud_bytes(cloud), 48, 64, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], 12, 12 * 64)
    assert np.array_equal(cloud_from_msg(msg), cloud, equal_nan=True)


def test_padded_points_extra_fields_and_padded_rows() -> None:
    cloud = sample_cloud()
    h, w = cloud.shape[:2]
    raw = np.zeros((h, w * 32 + 8), dtype=np.uint8)  # 32-byte points (x y z pad rgb ...), 8 bytes row padding
    points = raw[:, : w * 32].reshape(h, w, 32)
    points[..., 0:12] = cloud.view(np.uint8).reshape(h, w, 12)
    points[..., 16:20] = 255
    fields = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("rgb", 16, 7)]
    msg = ros_message(raw.tobytes(), h, w, fields, 32, w * 32 + 8)
    assert np.array_equal(cloud_from_msg(msg), cloud, equal_nan=True)


def test_big_endian_and_double_fields() -> None:
    cloud = sample_cloud()
    big = cloud.astype(">f4").tobytes()
    msg = ros_message(big, 48, 64, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], 12, 768, big_endian=True)
    assert np.array_equal(cloud_from_msg(msg), cloud, equal_nan=True)
    double = cloud.astype("<f8").tobytes()
    msg = ros_message(double, 48, 64, [("x", 0, 8), ("y", 8, 8), ("z", 16, 8)], 24, 24 * 64)
    assert np.array_equal(cloud_from_msg(msg), cloud, equal_nan=True)


def test_a_rosbags_message_reads_the_same() -> None:
    store = get_typestore(Stores.ROS2_JAZZY)
    types = store.types
    cloud = sample_cloud()
    fields = [
        types["sensor_msgs/msg/PointField"](name=n, offset=4 * k, datatype=7, count=1)
        for k, n in enumerate("xyz")
    ]
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=1, nanosec=2), frame_id="f"
    )
    msg = types["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=48,
        width=64,
        fields=fields,
        is_bigendian=False,
        point_step=12,
        row_step=768,
        data=np.frombuffer(cloud_bytes(cloud), dtype=np.uint8),
        is_dense=False,
    )
    raw = store.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
    assert np.array_equal(
        cloud_from_msg(store.deserialize_cdr(raw, "sensor_msgs/msg/PointCloud2")), cloud, equal_nan=True
    )


@pytest.mark.parametrize(
    "change, reason",
    [
        (dict(height=0, width=0, data=b""), "empty cloud"),
        (dict(fields=[("x", 0, 7), ("y", 4, 7)]), "no z field"),
        (dict(fields=[("x", 0, 7), ("y", 4, 7), ("z", 8, 2)]), "must all be FLOAT32"),
        (dict(data=b"\0" * 100), "data holds 100 bytes"),
        (dict(point_step=8), "too small"),
        (dict(fields=[("x", 0, 7), ("y", 4, 7), ("z", 10, 7)]), "outside point_step"),
    ],
)
def test_unreadable_clouds_raise_a_one_line_reason(change: dict, reason: str) -> None:  # type: ignore[type-arg]
    cloud = sample_cloud()
    spec = dict(
        data=cloud_bytes(cloud),
        height=48,
        width=64,
        fields=[("x", 0, 7), ("y", 4, 7), ("z", 8, 7)],
        point_step=12,
        row_step=768,
    )
    spec.update(change)
    msg = ros_message(**spec)  # type: ignore[arg-type]
    with pytest.raises(CloudError, match=reason):
        cloud_from_msg(msg)
