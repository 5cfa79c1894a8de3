"""Tile classification from physical and virtual support, exactly as the paper (section 2.2.3).

"For every tile t_i, denote the number of physical and virtual support points by p_i and v_i ...
r = min(v_i/p_i, p_i/v_i), t_r is a threshold value for this ratio, set to 0.7 ... Support below a
threshold of 100 points is set to 0.
- v_i = 0 => the tile is occluded.
- v_i != 0 and p_i = 0 => the tile is missing.
- v_i != 0 and p_i != 0 and r <= t_r => the tile is missing.
- v_i != 0 and p_i != 0 and r > t_r => the tile is present."

The state codes are those of `tiling_assembly_msgs/TileState`.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np
from numpy.typing import NDArray


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
