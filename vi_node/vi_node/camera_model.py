"""The depth camera's pinhole model and its optical frame (paper section 2.2.2: "the Kinect's
optical properties (resolution, view angles)").

Clouds are organized images in `camera_depth_optical_frame` (REP 103/105: z forward, x right,
y down): pixel (u, v) holds the point (x, y, z) with u = fx x / z + cx, v = fy y / z + cy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import rotation_from_rpy

Array = NDArray[np.float64]

# camera_link (x forward, y left, z up) -> camera_depth_optical_frame: the standard rpy (-pi/2, 0, -pi/2)
OPTICAL_FROM_LINK = rotation_from_rpy(-math.pi / 2, 0.0, -math.pi / 2)


@dataclass(frozen=True)
class PinholeCamera:
    """Intrinsics (px) of a `width` x `height` depth image."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def at_resolution(self, width: int, height: int) -> PinholeCamera:
        """The same camera delivering `width` x `height` images (a binned or cropped-free mode).

        Raises ValueError when the aspect ratio differs: that is another camera, not a mode.
        """
        if width == self.width and height == self.height:
            return self
        sx, sy = width / self.width, height / self.height
        if abs(sx - sy) > 0.01 * max(sx, sy):
            raise ValueError(
                f"a {width}x{height} cloud does not match the {self.width}x{self.height} intrinsics "
                "(different aspect ratio)"
            )
        return PinholeCamera(
            self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5, width, height
        )

    @cached_property
    def rays(self) -> NDArray[np.float32]:
        """(H, W, 3) ray direction of every pixel in the optical frame, scaled so that z = 1."""
        v, u = np.mgrid[0 : self.height, 0 : self.width].astype(np.float64)
        rays = np.stack([(u - self.cx) / self.fx, (v - self.cy) / self.fy, np.ones_like(u)], axis=-1)
        return rays.astype(np.float32)

    def project(self, points: Array) -> tuple[Array, Array]:
        """Pixel coordinates (u, v) of points (N, 3) in the optical frame (z > 0)."""
        z = points[:, 2]
        return self.fx * points[:, 0] / z + self.cx, self.fy * points[:, 1] / z + self.cy

    def box_roi(self, pose: Array, low: Array, high: Array, margin_px: int = 4) -> tuple[slice, slice]:
        """Rows and columns of the image that can see the axis-aligned box [low, high] (map frame).

        `pose` is the 4x4 pose of the optical frame in the map. The whole image when a corner of the
        box is behind or very close to the camera (its projection is then not a bound).
        """
        corners = np.array(
            [[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1]) for z in (low[2], high[2])]
        )
        local = (corners - pose[:3, 3]) @ pose[:3, :3]
        if np.any(local[:, 2] < 0.05):
            return slice(0, self.height), slice(0, self.width)
        u, v = self.project(local)
        u0 = int(np.clip(np.floor(u.min()) - margin_px, 0, self.width))
        u1 = int(np.clip(np.ceil(u.max()) + margin_px + 1, 0, self.width))
        v0 = int(np.clip(np.floor(v.min()) - margin_px, 0, self.height))
        v1 = int(np.clip(np.ceil(v.max()) + margin_px + 1, 0, self.height))
        return slice(v0, v1), slice(u0, u1)

    def check_cloud(self, cloud: NDArray[np.float32], tolerance: float = 0.02) -> str | None:
        """Why the organized cloud was not made with these intrinsics, or None when it was.

        A driver builds x = (u - cx) z / fx and y = (v - cy) z / fy: sampled points must agree.
        """
        rows = np.linspace(0, self.height - 1, 24).astype(int)
        cols = np.linspace(0, self.width - 1, 32).astype(int)
        sample = cloud[np.ix_(rows, cols)]
        ok = np.isfinite(sample).all(axis=-1) & (sample[..., 2] > 0.1)
        if ok.sum() < 20:
            return None
        expected = self.rays[np.ix_(rows, cols)][ok] * sample[ok][:, 2:3]
        error = np.abs(expected[:, :2] - sample[ok][:, :2]).max(axis=1)
        reach = np.abs(sample[ok][:, :2]).max(axis=1) + 0.01
        if np.median(error / reach) > tolerance:
            return (
                f"the cloud's x/y do not match the intrinsics fx={self.fx:.1f} fy={self.fy:.1f} "
                f"cx={self.cx:.1f} cy={self.cy:.1f} at {self.width}x{self.height}"
            )
        return None
