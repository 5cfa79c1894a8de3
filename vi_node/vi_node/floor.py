"""Floor-based correction of the camera's height, roll and pitch (paper section 2.2.1, second step).

"We perform floor detection in the point cloud C_p ... a transformation T_f, which aligns the
floor's normal with the vertical axis ... has no rotation about the vertical axis, i.e. the
Kinect's yaw, as previously determined by the overhead system, is not altered ... only the vertical
position of K_v is affected."

The floor is fitted on a subsample of the organized cloud, near where the pose prior predicts it
(and away from the expected structure), by a noise-weighted total least squares plane with
outlier trimming. The correction keeps the camera's yaw (of its `camera_link` in yaw-pitch-roll
form) and horizontal position, and takes roll, pitch and height from the fitted plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import rotation_from_rpy, rpy_from_rotation
from vi_node.camera_model import OPTICAL_FROM_LINK
from vi_node.depth_noise import axial_sigma

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FloorSettings:
    """How the floor is searched for."""

    stride: int = 4  # use every stride-th row and column
    band: float = 0.04  # m, predicted height window at the camera ...
    band_slope: float = 0.05  # ... widened by this much per metre of range (prior roll/pitch errors)
    max_range: float = 3.5  # m, beyond this the Kinect's noise makes points useless for the fit
    keep_out: float = 0.05  # m, ignore points this close (in x, y) to the expected structure's box
    max_tilt: float = math.radians(6.0)  # largest believable correction of roll/pitch (rocking, mount)
    max_height_change: float = 0.15  # m, largest believable correction of the camera height
    min_points: int = 150
    sample_size: int = 600  # floor points kept for the alignment
    consensus_trials: int = 40  # planes tried through 3 random candidates


@dataclass(frozen=True)
class FloorFit:
    """The floor plane in the optical frame: unit normal (pointing up, to the camera side) and the
    camera's height above it; how many points carried the fit, their RMS distance to it, and a
    sample of them (optical frame) for aligning to the floor later."""

    normal: Array
    height: float
    points: int
    rms: float
    sample: Array


def fit_floor(
    cloud: NDArray[np.float32],
    prior: Array,
    keep_out_low: Array,
    keep_out_high: Array,
    settings: FloorSettings | None = None,
) -> FloorFit | None:
    """Fit the floor plane near where `prior` (4x4 optical pose in map) predicts it; None if absent."""
    settings = settings or FloorSettings()
    points = _floor_candidates(cloud, prior, keep_out_low, keep_out_high, settings, settings.stride)
    if len(points) < 4 * settings.min_points and settings.stride > 2:
        # little floor in view (a low camera, robots around): look at more pixels
        points = _floor_candidates(cloud, prior, keep_out_low, keep_out_high, settings, settings.stride // 2)
    if len(points) < settings.min_points:
        return None
    up_prior = prior[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    keep = _consensus(points, up_prior, prior[2, 3], settings)
    if keep is None:
        return None
    weights = 1.0 / axial_sigma(points[:, 2]) ** 2
    normal, offset = up_prior, 0.0
    for _ in range(3):
        normal, offset = _weighted_plane(points[keep], weights[keep], up_prior)
        new_keep = np.abs(points @ normal - offset) / axial_sigma(points[:, 2]) < 3.0
        if new_keep.sum() < settings.min_points:
            return None
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    height = -offset  # the floor lies below the camera: normal . p = -height on it
    tilt = math.acos(float(np.clip(normal @ up_prior, -1.0, 1.0)))
    if tilt > settings.max_tilt or abs(height - prior[2, 3]) > settings.max_height_change:
        return None
    inliers = points[keep]
    rms = float(np.sqrt(np.mean((inliers @ normal - offset) ** 2)))
    sample = inliers[:: max(1, len(inliers) // settings.sample_size)]
    return FloorFit(normal=normal, height=height, points=len(inliers), rms=rms, sample=sample)


def _floor_candidates(
    cloud: NDArray[np.float32],
    prior: Array,
    keep_out_low: Array,
    keep_out_high: Array,
    settings: FloorSettings,
    stride: int,
) -> Array:
    """Points (optical frame) near where the prior predicts the floor, away from the structure."""
    s = max(1, stride)
    rotation, origin = prior[:3, :3], prior[:3, 3]
    sample = cloud[::s, ::s]
    # predicted height first (one row of the rotation), on the whole subsample at once
    height = sample @ rotation[2].astype(np.float32) + np.float32(origin[2])
    depth = sample[..., 2]
    with np.errstate(invalid="ignore"):  # NaN compares False
        near_floor = (np.abs(height) < settings.band + settings.band_slope * depth) & (
            depth < settings.max_range
        )
    points = sample[near_floor].astype(np.float64)
    world_xy = points @ rotation[:2].T + origin[:2]
    low, high = keep_out_low[:2] - settings.keep_out, keep_out_high[:2] + settings.keep_out
    return points[np.any((world_xy < low) | (world_xy > high), axis=1)]


def _consensus(
    points: Array, up_prior: Array, prior_height: float, settings: FloorSettings
) -> NDArray[np.bool_] | None:
    """The points of the plane (within max_tilt and max_height_change of the prior's floor) that
    most of them lie on: the floor, not the tops of tiles or boxes on it, not the feet of robots."""
    rng = np.random.default_rng(len(points))  # the same scan gives the same fit
    sigma = axial_sigma(points[:, 2])
    best, best_count = None, 0
    triples = rng.integers(0, len(points), size=(settings.consensus_trials, 3))
    for a, b, c in triples:
        normal = np.cross(points[b] - points[a], points[c] - points[a])
        length = float(np.linalg.norm(normal))
        if length < 1e-9:
            continue
        normal /= length
        if normal @ up_prior < 0:
            normal = -normal
        offset = float(normal @ points[a])
        if normal @ up_prior < math.cos(settings.max_tilt) or abs(-offset - prior_height) > settings.max_height_change:
            continue
        inliers = np.abs(points @ normal - offset) < 3.0 * sigma + 0.002
        count = int(inliers.sum())
        if count > best_count:
            best, best_count = inliers, count
    if best is None or best_count < settings.min_points:
        return None
    return best


def _weighted_plane(points: Array, weights: Array, up: Array) -> tuple[Array, float]:
    """Noise-weighted total least squares plane: unit normal (towards `up`) and offset."""
    centre = (weights[:, None] * points).sum(axis=0) / weights.sum()
    centred = points - centre
    covariance = (weights[:, None] * centred).T @ centred
    _, vectors = np.linalg.eigh(covariance)
    normal = vectors[:, 0]
    if normal @ up < 0:
        normal = -normal
    return normal, float(normal @ centre)


def correct_pose(prior: Array, floor: FloorFit) -> Array:
    """The prior with roll, pitch and height from the floor; yaw and x, y unchanged."""
    link_rotation = prior[:3, :3] @ OPTICAL_FROM_LINK.T
    yaw = rpy_from_rotation(link_rotation)[2]
    # the map's up axis seen from camera_link is (-sin p, sin r cos p, cos r cos p)
    up = OPTICAL_FROM_LINK @ floor.normal
    pitch = math.asin(float(np.clip(-up[0], -1.0, 1.0)))
    roll = math.atan2(float(up[1]), float(up[2]))
    corrected = np.eye(4)
    corrected[:3, :3] = rotation_from_rpy(roll, pitch, yaw) @ OPTICAL_FROM_LINK
    corrected[:3, 3] = (prior[0, 3], prior[1, 3], floor.height)
    return corrected
