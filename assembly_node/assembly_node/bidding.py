"""A robot's bid for re-placing a missing tile (paper section 2.3, equation 1).

    b_i = w_i - A * c_i + B * d_ij

w_i is the robot's remaining workload (s, under the time model), c_i how many of its still-to-place
tiles the missing tile directly supports, d_ij the floor distance from the robot's cache of the
tile's type to the tile (m). A (s per supported tile) and B (s per metre) weigh them; the lowest
bid wins. A robot whose own tiles wait for the missing tile (large c_i) and whose cache is near
(small d_ij) bids low.

Beyond the paper, a repair of a tile lying wrong is bid for with the same formula, d_ij measured
from where the robot stands now (its overhead pose; its cache when it has not heard one): the robot
must go to the wrong tile first, and only then to a cache.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel


@dataclass(frozen=True)
class Bid:
    """The terms and the value of one bid."""

    workload: float  # s, w_i
    supported_count: int  # c_i
    cache_distance: float  # m, d_ij
    value: float  # b_i


def compute_bid(
    structure: Structure,
    time_model: TimeModel,
    remaining: Sequence[int],
    tile_id: int,
    cache: tuple[float, float] | None,
    weight_supported: float,
    weight_distance: float,
) -> Bid:
    """The bid of a robot with `remaining` tiles to place for the missing `tile_id`.

    `cache` is the robot's parts cache for the tile's type ((x, y), m); None when it has none,
    which counts as distance 0 (the robot is assumed to fetch it where the structure's file says).
    """
    workload = time_model.workload(structure, [t for t in remaining if t != tile_id])
    supported = sum(1 for t in remaining if t != tile_id and tile_id in structure.supports[t])
    distance = 0.0
    if cache is not None:
        centre = structure.tiles[tile_id].centroid
        distance = math.hypot(centre[0] - cache[0], centre[1] - cache[1])
    value = workload - weight_supported * supported + weight_distance * distance
    return Bid(workload=workload, supported_count=supported, cache_distance=distance, value=value)


def compute_repair_bid(
    structure: Structure,
    time_model: TimeModel,
    remaining: Sequence[int],
    tile_id: int,
    standing_at: tuple[float, float] | None,
    weight_supported: float,
    weight_distance: float,
) -> Bid:
    """The bid for repairing `tile_id`: as `compute_bid`, the distance from `standing_at` (x, y)."""
    return compute_bid(structure, time_model, remaining, tile_id, standing_at, weight_supported, weight_distance)
