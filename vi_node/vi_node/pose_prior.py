"""Pose prior of the depth camera from the overhead localization (paper section 2.2.1, first step).

"An overhead localization system gives an estimate of the horizontal position of K_p ... as well
as the yaw": x, y and yaw of the VI robot's `base_link` in `map`. Composed with the camera mount
(`camera_link` in `base_link`, xyz + rpy, REP 103) and the fixed optical rotation, it gives the
pose prior of `camera_depth_optical_frame` in `map` as a 4x4 homogeneous matrix. Height, roll and
pitch come from the mount alone until the floor corrects them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import rotation_from_quaternion, rotation_from_rpy, rpy_from_rotation
from vi_node.camera_model import OPTICAL_FROM_LINK

Array = NDArray[np.float64]


@dataclass(frozen=True)
class CameraMount:
    """Pose of `camera_link` in `base_link`: position (m) and roll, pitch, yaw (rad)."""

    xyz: tuple[float, float, float]
    rpy: tuple[float, float, float]

    def optical_in_base(self) -> Array:
        """4x4 pose of the optical frame in `base_link`."""
        pose = np.eye(4)
        pose[:3, :3] = rotation_from_rpy(*self.rpy) @ OPTICAL_FROM_LINK
        pose[:3, 3] = self.xyz
        return pose


@dataclass(frozen=True)
class OverheadPose:
    """What the overhead cameras report of the VI robot: x, y (m) and yaw (rad) in `map`."""

    x: float
    y: float
    yaw: float

    @classmethod
    def from_quaternion(cls, x: float, y: float, qx: float, qy: float, qz: float, qw: float) -> OverheadPose:
        """From a PoseStamped's position and orientation (only the yaw of the rotation is used)."""
        return cls(x, y, rpy_from_rotation(rotation_from_quaternion(qx, qy, qz, qw))[2])

    def base_pose(self) -> Array:
        """4x4 pose of `base_link` in `map`: on the floor, level."""
        pose = np.eye(4)
        pose[:3, :3] = rotation_from_rpy(0.0, 0.0, self.yaw)
        pose[:3, 3] = (self.x, self.y, 0.0)
        return pose


def camera_prior(overhead: OverheadPose, mount: CameraMount) -> Array:
    """4x4 pose prior of `camera_depth_optical_frame` in `map`."""
    return overhead.base_pose() @ mount.optical_in_base()


def pose_error(estimate: Array, truth: Array) -> tuple[float, float]:
    """Distance (m) between the two poses' origins and the angle (rad) of the relative rotation."""
    translation = float(np.linalg.norm(estimate[:3, 3] - truth[:3, 3]))
    relative = estimate[:3, :3].T @ truth[:3, :3]
    angle = math.acos(float(np.clip((np.trace(relative) - 1.0) / 2.0, -1.0, 1.0)))
    return translation, angle


def invert(pose: Array) -> Array:
    """Inverse of a rigid 4x4 transform."""
    inverse = np.eye(4)
    inverse[:3, :3] = pose[:3, :3].T
    inverse[:3, 3] = -pose[:3, :3].T @ pose[:3, 3]
    return inverse
