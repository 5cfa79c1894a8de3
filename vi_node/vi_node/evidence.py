"""Per-pixel evidence: measured against virtual depth, tile by tile (beyond paper section 2.2.3).

The paper compares only how many points support each tile. Here every pixel the virtual scan C_v
gives to tile i is compared with the measured depth at the same pixel (the aligned pose makes the
two images line up), with a tolerance that follows the Kinect's noise at that depth:

- measured within the tolerance of the virtual depth: the tile's surface is there (agree);
- measured clearly *behind* it: the camera sees through where tile i should be (see-through,
  evidence that it is missing);
- measured clearly *in front*: something else hides it (in front, no evidence either way);
- no return: no data.

Only pixels away from depth edges (where a pixel of lateral noise or of pose error flips the
answer) and not at grazing incidence are judged. Tiles are then decided
relative to what the virtual scan predicts for them (so a 4 cm tile at 2 m, a few dozen pixels,
is judged on those), not on a fixed count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from vi_node.classify import TileState
from vi_node.raycast import VirtualScan

Counts = NDArray[np.int64]


@dataclass(frozen=True)
class EvidenceSettings:
    depth_sigmas: float = 3.0  # agreement within this many axial noise sigmas ...
    depth_margin: float = 0.005  # m, ... plus this (model, placement and pose error), / cos(incidence)
    max_incidence: float = math.radians(82.0)  # more oblique pixels are not judged
    min_observed_pixels: int = 8  # a tile needs this many judged pixels with data ...
    min_observed_fraction: float = 0.15  # ... and this share of the pixels it should fill
    present_fraction: float = 0.7  # present when this share of the observed pixels agree
    missing_fraction: float = 0.6  # missing when this share of the observed pixels see through


@dataclass
class TileEvidence:
    """Pixel counts per tile (arrays indexed like the expected model's tiles)."""

    agree: Counts
    see_through: Counts
    in_front: Counts
    no_return: Counts
    judged: Counts  # pixels of the tile that were judged (interior, not grazing, in range)
    virtual: Counts  # v_i: every pixel the virtual scan gives the tile

    @property
    def observed(self) -> Counts:
        return self.agree + self.see_through

    @classmethod
    def zeros(cls, count: int) -> TileEvidence:
        z = np.zeros(count, dtype=np.int64)
        return cls(z.copy(), z.copy(), z.copy(), z.copy(), z.copy(), z.copy())

    def __add__(self, other: TileEvidence) -> TileEvidence:
        return TileEvidence(
            self.agree + other.agree,
            self.see_through + other.see_through,
            self.in_front + other.in_front,
            self.no_return + other.no_return,
            self.judged + other.judged,
            self.virtual + other.virtual,
        )

    def take(self, index: int) -> TileEvidence:
        """The evidence of one tile, as arrays of length 1."""
        s = slice(index, index + 1)
        return TileEvidence(
            self.agree[s],
            self.see_through[s],
            self.in_front[s],
            self.no_return[s],
            self.judged[s],
            self.virtual[s],
        )


def depth_tolerance(
    depth: NDArray[np.float32], cos_incidence: NDArray[np.float32], settings: EvidenceSettings
) -> NDArray[np.float32]:
    """How far (m) a measured depth may lie from the virtual one and still be the same surface.

    Axial noise (Nguyen et al. 2012) and half a disparity step (Khoshelham 2012) at that depth,
    plus a margin for model and pose error that grows on oblique faces.
    """
    sigma = 0.0012 + 0.0019 * (depth - 0.4) ** 2
    step = 2.85e-3 * depth**2
    return (
        settings.depth_sigmas * sigma + 0.5 * step + settings.depth_margin / np.maximum(cos_incidence, 0.2)
    ).astype(np.float32)


def interior(tile: NDArray[np.int64], depth: NDArray[np.float32]) -> NDArray[np.bool_]:
    """Pixels of a tile away from depth edges: their four neighbours are at nearly the same depth.

    At a depth edge a pixel of lateral noise or of pose error shows the background instead of the
    tile; between two tiles at the same depth (adjacent top faces) nothing is lost, so thin tiles
    seen from afar keep their pixels.
    """
    jump = 0.01 + 0.02 * np.where(np.isfinite(depth), depth, 0.0)
    inside = tile >= 0
    dy = np.abs(np.diff(depth, axis=0)) <= np.minimum(jump[1:, :], jump[:-1, :])  # False across inf
    dx = np.abs(np.diff(depth, axis=1)) <= np.minimum(jump[:, 1:], jump[:, :-1])
    inside[1:, :] &= dy
    inside[:-1, :] &= dy
    inside[:, 1:] &= dx
    inside[:, :-1] &= dx
    inside[0, :] = inside[-1, :] = False
    inside[:, 0] = inside[:, -1] = False
    return inside


def pixel_evidence(
    cloud: NDArray[np.float32], virtual: VirtualScan, tile_count: int, settings: EvidenceSettings
) -> TileEvidence:
    """Compare the measured depth with the virtual depth on every pixel of the virtual scan."""
    tile = virtual.tile
    counts = TileEvidence.zeros(tile_count)
    if tile.size == 0:
        return counts
    counts.virtual = np.bincount(tile[tile >= 0], minlength=tile_count).astype(np.int64)
    judged = interior(tile, virtual.depth) & (virtual.cos_incidence >= math.cos(settings.max_incidence))
    if not judged.any():
        return counts
    owner = tile[judged]
    expected = virtual.depth[judged]
    measured = cloud[virtual.rows, virtual.cols, 2][judged]
    tolerance = depth_tolerance(expected, virtual.cos_incidence[judged], settings)
    missing = ~np.isfinite(measured)
    difference = np.where(missing, 0.0, measured - expected)
    agree = ~missing & (np.abs(difference) <= tolerance)
    behind = ~missing & (difference > tolerance)
    front = ~missing & (difference < -tolerance)
    counts.judged = np.bincount(owner, minlength=tile_count).astype(np.int64)
    counts.agree = np.bincount(owner[agree], minlength=tile_count).astype(np.int64)
    counts.see_through = np.bincount(owner[behind], minlength=tile_count).astype(np.int64)
    counts.in_front = np.bincount(owner[front], minlength=tile_count).astype(np.int64)
    counts.no_return = np.bincount(owner[missing], minlength=tile_count).astype(np.int64)
    return counts


def decide(evidence: TileEvidence, settings: EvidenceSettings) -> NDArray[np.int64]:
    """PRESENT, MISSING or OCCLUDED (undetermined) per tile from its pixel evidence.

    A tile is resolved when enough of the pixels the virtual scan predicts for it were observed
    (agree or see-through: in-front and no-return pixels say nothing about it); then the share of
    agreeing or see-through pixels decides.
    """
    observed = evidence.observed
    enough = (observed >= settings.min_observed_pixels) & (
        observed >= settings.min_observed_fraction * evidence.judged
    )
    share_agree = evidence.agree / np.maximum(observed, 1)
    share_through = evidence.see_through / np.maximum(observed, 1)
    state = np.full(len(observed), int(TileState.OCCLUDED), dtype=np.int64)
    state[enough & (share_agree >= settings.present_fraction)] = TileState.PRESENT
    state[enough & (share_through >= settings.missing_fraction)] = TileState.MISSING
    return state
