"""Candidate points C_1 for the alignment (paper section 2.2.1, candidate filtering).

"C_1 subset of C_p ... consists of a subset of points, being candidates for points belonging to
S_p ... Using this hierarchy of bounding boxes, C_1 results in a relatively small subset of C_p.
In addition, we omit points that belong to the floor."

Only the image rows and columns that can see the expected structure's bounding box are looked at
(the organized cloud makes that a slice, not a search), those points are put into the map frame,
and the ones inside the box (with a margin) and above the floor are kept, with their pixel.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vi_node.camera_model import PinholeCamera

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Candidates:
    """Points of the scan that may belong to the structure."""

    points: Array  # (N, 3) in the map frame under the pose they were selected with
    optical: Array  # (N, 3) the same points in the optical frame (as measured)
    pixels: NDArray[np.int64]  # (N,) flat pixel index (v * width + u) of each point

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, keep: NDArray[np.bool_] | NDArray[np.int64] | slice) -> Candidates:
        return Candidates(self.points[keep], self.optical[keep], self.pixels[keep])

    def moved(self, correction: Array) -> Candidates:
        """The same points with the map frame corrected by a 4x4 rigid transform."""
        return Candidates(self.points @ correction[:3, :3].T + correction[:3, 3], self.optical, self.pixels)


def select_candidates(
    cloud: NDArray[np.float32],
    camera: PinholeCamera,
    pose: Array,
    low: Array,
    high: Array,
    margin: float,
    floor_clearance: float,
    stride: int = 1,
    height_margin: float | None = None,
) -> Candidates:
    """Points within `margin` of the box [low, high] (map) and higher than `floor_clearance`.

    `pose` is the 4x4 pose of the optical frame in the map used to place the points; with
    `stride` > 1 only every stride-th row and column is looked at (for searches that need few points);
    `height_margin` above the box's top instead of `margin` (a search in x and y only).
    """
    box_low = np.array([low[0] - margin, low[1] - margin, floor_clearance])
    box_high = high + np.array([margin, margin, margin if height_margin is None else height_margin])
    rows, cols = camera.box_roi(pose, box_low, box_high)
    rows = slice(rows.start, rows.stop, stride)
    cols = slice(cols.start, cols.stop, stride)
    window = cloud[rows, cols]
    # height first (one row of the rotation): most of the window is floor, dropped before the rest
    rotation = pose[:3, :3].astype(np.float32)
    height = window @ rotation[2] + np.float32(pose[2, 3])
    with np.errstate(invalid="ignore"):
        level = (height >= box_low[2]) & (height <= box_high[2])  # NaN compares False
    row, col = np.nonzero(level)
    optical = window[row, col].astype(np.float64)
    world = optical @ pose[:3, :3].T + pose[:3, 3]
    inside = np.all((world[:, :2] >= box_low[:2]) & (world[:, :2] <= box_high[:2]), axis=1)
    pixels = (row[inside] * stride + rows.start) * camera.width + (col[inside] * stride + cols.start)
    return Candidates(world[inside], optical[inside], pixels.astype(np.int64))


def at_structure_range(points: Array, camera_xy: Array, low: Array, high: Array, margin: float) -> NDArray[np.bool_]:
    """Which `points` (N, 3, map) lie as far from the camera (in x, y) as some point of the box
    [low, high], within `margin` (the overhead position error and the box margin).

    An error of the overhead yaw turns the scene about the camera: it moves the structure sideways
    by up to a third of a metre at 1.5 m, but not nearer or farther. So the search for x, y and
    yaw needs a wide box around S_a sideways, but not in depth: a box of clutter half a metre in
    front of the structure (inside the wide box) pulled the search onto its faces.
    """
    x = np.clip(camera_xy[0], low[0], high[0])
    y = np.clip(camera_xy[1], low[1], high[1])
    nearest = math.hypot(camera_xy[0] - x, camera_xy[1] - y)
    corners = [(cx, cy) for cx in (low[0], high[0]) for cy in (low[1], high[1])]
    farthest = max(math.hypot(camera_xy[0] - cx, camera_xy[1] - cy) for cx, cy in corners)
    distance = np.hypot(points[:, 0] - camera_xy[0], points[:, 1] - camera_xy[1])
    return (distance >= nearest - margin) & (distance <= farthest + margin)
