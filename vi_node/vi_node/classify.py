"""Tile classification from physical and virtual support, exactly as the paper (section 2.2.3).

"For every tile t_i, denote the number of physical and virtual support points by p_i and v_i ...
r = min(v_i/p_i, p_i/v_i), t_r is a threshold value for this ratio, set to 0.7 ... Support below a
threshold of 100 points is set to 0.
- v_i = 0 => the tile is occluded.
- v_i != 0 and p_i = 0 => the tile is missing.
- v_i != 0 and p_i != 0 and r <= t_r => the tile is missing.
- v_i != 0 and p_i != 0 and r > t_r => the tile is present."

p_i counts the aligned candidate points that project onto tile i through the patch hierarchy
(section 2.2.1), v_i the virtual scan's points on it (section 2.2.2): `paper_support` counts both
and applies the rules. The state codes are those of `tiling_assembly_msgs/TileState`.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from vi_node.patches import PlanarPatches
from vi_node.raycast import VirtualScan


class TileState(IntEnum):
    """Same values as the constants of tiling_assembly_msgs/TileState."""

    UNKNOWN = 0
    PRESENT = 1
    MISSING = 2
    OCCLUDED = 3
    MISPLACED = 4

    @property
    def label(self) -> str:
        return self.name.lower()


def support_ratio(physical: NDArray[np.int64], virtual: NDArray[np.int64]) -> NDArray[np.float64]:
    """r = min(v/p, p/v), 0 where either count is 0."""
    p = np.asarray(physical, dtype=np.float64)
    v = np.asarray(virtual, dtype=np.float64)
    both = (p > 0) & (v > 0)
    ratio = np.zeros(np.broadcast(p, v).shape)
    ratio[both] = np.minimum(p[both] / v[both], v[both] / p[both])
    return ratio


def classify_paper(
    physical: NDArray[np.int64],
    virtual: NDArray[np.int64],
    min_support: int = 100,
    ratio_threshold: float = 0.7,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """States (TileState values) and ratios r of tiles with support counts p_i and v_i."""
    p = np.where(np.asarray(physical) < min_support, 0, physical)
    v = np.where(np.asarray(virtual) < min_support, 0, virtual)
    ratio = support_ratio(p, v)
    state = np.where(
        v == 0,
        TileState.OCCLUDED,
        np.where((p == 0) | (ratio <= ratio_threshold), TileState.MISSING, TileState.PRESENT),
    )
    return state.astype(np.int64), ratio


@dataclass(frozen=True)
class PaperSupport:
    """Per tile (in the patches' order): p_i, v_i, r, the RMS distance of the p_i points to the
    tile, and the state by the paper's rules."""

    physical: NDArray[np.int64]
    virtual: NDArray[np.int64]
    ratio: NDArray[np.float64]
    residual: NDArray[np.float64]
    states: NDArray[np.int64]


def paper_support(
    *,
    patches: PlanarPatches,
    points: NDArray[np.float64],
    virtual: VirtualScan,
    rays: NDArray[np.float32],
    pose: NDArray[np.float64],
    support_distance: float,
    floor_clearance: float,
    min_support: int,
    ratio_threshold: float,
) -> PaperSupport:
    """p_i from the aligned candidate `points` (map) projected onto S_a within `support_distance`,
    v_i from the virtual scan (whose `rays` are the camera's, `pose` the aligned optical frame),
    and the paper's states."""
    count = len(patches)
    projection = patches.project(points, support_distance, pose[:3, 3])
    found = projection.found
    physical = np.bincount(projection.tile[found], minlength=count).astype(np.int64)
    squared = np.bincount(projection.tile[found], weights=projection.distance[found] ** 2, minlength=count)
    residual = np.sqrt(squared / np.maximum(physical, 1))
    # the candidates lost everything lower than floor_clearance: so must the virtual points,
    # or every tile standing on the floor would look half missing
    visible = virtual.tile >= 0
    directions = rays[virtual.rows, virtual.cols][visible]
    height = (directions * virtual.depth[visible][:, None]) @ pose[2, :3] + pose[2, 3]
    kept = virtual.tile[visible][height >= floor_clearance]
    virtual_support = np.bincount(kept, minlength=count).astype(np.int64)
    states, ratio = classify_paper(physical, virtual_support, min_support, ratio_threshold)
    return PaperSupport(physical, virtual_support, ratio, residual, states)
