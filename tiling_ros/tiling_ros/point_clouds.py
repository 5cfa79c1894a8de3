"""Organized XYZ numpy clouds <-> sensor_msgs/PointCloud2, without Python loops over points.

`cloud_from_msg` reads any object with PointCloud2's fields (an rclpy message or a `rosbags` one):
the x, y, z fields are read straight out of `data` with a strided view (any point_step, offsets,
padding, row_step), so a 640x480 cloud costs one copy. A cloud that cannot be read raises
CloudError with a one-line reason. `cloud_to_msg` writes the one layout the project publishes:
x, y, z float32, point_step 12, little endian, NaN where there is no return.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

FLOAT32 = 7  # sensor_msgs/PointField.FLOAT32
FLOAT64 = 8
POINT_STEP = 12  # bytes of one x, y, z float32 point as written by `cloud_to_msg`


class CloudError(ValueError):
    """A PointCloud2 that is not an organized x, y, z cloud we can read."""


def cloud_from_msg(msg: Any) -> NDArray[np.float32]:
    """The organized (height, width, 3) float32 cloud of a PointCloud2 (NaN = no return)."""
    height, width = int(msg.height), int(msg.width)
    point_step, row_step = int(msg.point_step), int(msg.row_step)
    if height * width == 0:
        raise CloudError("empty cloud (0 points)")
    offsets: dict[str, tuple[int, int]] = {}
    for f in msg.fields:
        offsets[str(f.name)] = (int(f.offset), int(f.datatype))
    missing = [n for n in "xyz" if n not in offsets]
    if missing:
        raise CloudError(
            f"cloud has no {', '.join(missing)} field(s) (fields: {', '.join(offsets) or 'none'})"
        )
    kinds = {offsets[n][1] for n in "xyz"}
    if not kinds <= {FLOAT32, FLOAT64} or len(kinds) != 1:
        raise CloudError("x, y, z must all be FLOAT32 (or all FLOAT64)")
    size = 4 if kinds == {FLOAT32} else 8
    if point_step < 3 * size or row_step < width * point_step:
        raise CloudError(
            f"point_step {point_step} / row_step {row_step} too small for {width} points of x, y, z"
        )
    if any(offsets[n][0] + size > point_step for n in "xyz"):
        raise CloudError("a field lies outside point_step")
    data = msg.data
    buffer = data if isinstance(data, bytes | bytearray | memoryview) else memoryview(data)
    raw = np.frombuffer(buffer, dtype=np.uint8)
    if raw.size < (height - 1) * row_step + width * point_step:
        raise CloudError(f"data holds {raw.size} bytes, {height}x{width} points need {height * row_step}")
    dtype = np.dtype(">f4" if size == 4 else ">f8") if bool(msg.is_bigendian) else np.dtype(f"<f{size}")
    cloud = np.empty((height, width, 3), dtype=np.float32)
    for axis, name in enumerate("xyz"):
        view = np.ndarray(
            shape=(height, width),
            dtype=dtype,
            buffer=raw,
            offset=offsets[name][0],
            strides=(row_step, point_step),
        )
        cloud[..., axis] = view
    return cloud


def cloud_fields() -> list[tuple[str, int, int, int]]:
    """(name, offset, datatype, count) of the x, y, z float32 layout written by `cloud_bytes`."""
    return [("x", 0, FLOAT32, 1), ("y", 4, FLOAT32, 1), ("z", 8, FLOAT32, 1)]


def cloud_bytes(cloud: NDArray[np.float32]) -> bytes:
    """The `data` of a PointCloud2 with fields x, y, z float32, point_step 12, little endian."""
    return _xyz_array(cloud).tobytes()


def cloud_to_msg(cloud: NDArray[np.floating], header: Any, *, cloud_type: Any = None,
                 field_type: Any = None) -> Any:
    """An organized (H, W, 3) cloud as an x, y, z float32 PointCloud2 with `header`.

    A sensor_msgs/PointCloud2 by default; another library's PointCloud2 and PointField classes
    (a `rosbags` typestore's) may be given instead, whose `data` is then a uint8 numpy array.
    """
    array = _xyz_array(cloud)
    height, width = array.shape[:2]
    if cloud_type is None or field_type is None:
        from sensor_msgs.msg import PointCloud2, PointField

        cloud_type, field_type, data = PointCloud2, PointField, array.tobytes()
    else:
        data = array.reshape(-1).view(np.uint8)
    return cloud_type(
        header=header,
        height=height,
        width=width,
        fields=[field_type(name=n, offset=o, datatype=d, count=c) for n, o, d, c in cloud_fields()],
        is_bigendian=False,
        point_step=POINT_STEP,
        row_step=POINT_STEP * width,
        data=data,
        is_dense=False,
    )


def _xyz_array(cloud: NDArray[np.floating]) -> NDArray[np.float32]:
    array = np.ascontiguousarray(cloud, dtype="<f4")
    if array.ndim != 3 or array.shape[2] != 3:
        raise CloudError(f"expected an (H, W, 3) cloud, got shape {array.shape}")
    return array
