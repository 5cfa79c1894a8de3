"""A tile of the planned type against a tile of another type in its place, pixel by pixel (beyond
the paper; its section 5 names "identification of incorrect assembly placements" as future work).

A robot that takes a tile from the wrong cache places it where the planned one goes, at the planned
pose. When the two shapes cover much the same place (a triangle where a 4 cm square was planned
covers 62% of it), most of the tile's pixels agree with the planned tile, the rest see through
where nothing moved explains it, and neither "moved" nor "missing" fits. Only the pixels where the
two hypotheses predict different depths can tell them apart: ray cast S_a as planned, and S_a with
the tile swapped for each other type of the same height (the first surface behind the planned tile,
or the rival tile where it stands in front of that), and let each such pixel vote for the
hypothesis whose depth it measures (`evidence.depth_tolerance`). Pixels both or neither explain, at
depth edges, blank, at grazing incidence or on a robot say nothing. Something of another shape lies
there when the rival wins a clear majority of enough pixels; a tile of the planned type wins its own
pixels, whatever noise or a small pose error does to the few at its edges.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile, TileShape
from tiling_assembly.polygons import convex_overlap_area, is_convex, signed_area, triangulate
from vi_node.evidence import EvidenceSettings, depth_tolerance, smooth
from vi_node.pose_hypotheses import DepthImage
from vi_node.raycast import VirtualScan, VirtualScene

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]


@dataclass(frozen=True)
class TypeVotes:
    """Pixels where the two hypotheses predict different depths, by the one the measurement fits."""

    planned: int
    rival: int
    rival_seen: int = 0  # pixels of the rival's own surface measured there, where a tile gone would not be
    rival_missed: int = 0  # pixels of the rival's own surface measured clearly behind it

    def rival_explains(self, share: float, min_pixels: int) -> bool:
        """Whether the rival type wins at least `min_pixels` pixels and `share` of the decided ones,
        and its own surface is seen where only it explains the depth, on at least `min_pixels`
        pixels and `share` of those that decide between it and what lies behind it. A tile that is
        gone leaves the pixels outside a smaller rival as the rival predicts them; its own place is
        then empty, out of sight, or shows what lay below (the octagon under a long rectangle)."""
        if self.rival < min_pixels or self.rival < share * (self.rival + self.planned):
            return False
        return self.rival_seen >= min_pixels and self.rival_seen >= share * (self.rival_seen + self.rival_missed)

    def rival_as_likely(self, min_pixels: int) -> bool:
        """Whether the rival type explains at least `min_pixels` of the pixels where the two differ,
        and no fewer than the planned type: the tile cannot be shown to be of its planned type."""
        return self.rival >= min_pixels and self.rival >= self.planned


def rival_tiles(tile: PlacedTile, shapes: Mapping[str, TileShape]) -> list[PlacedTile]:
    """The tile swapped for every other type of its height (within 1 mm), at its planned pose."""
    height = _height(tile.shape)
    return [
        PlacedTile(tile.tile_id, name, shape, tile.rotation, tile.position)
        for name, shape in sorted(shapes.items())
        if name != tile.type_name and abs(_height(shape) - height) < 1e-3
    ]


def look_alike_rivals(tile: PlacedTile, shapes: Mapping[str, TileShape], share: float) -> list[PlacedTile]:
    """Of `rival_tiles`, those whose footprint shares at least `share` of the two footprints' union
    with the tile's (a 5 x 4.3 cm triangle and a 4 cm square: 0.5): few pixels tell such a rival from
    the tile, and a swap leaves nearly all the tile's own pixels agreeing."""
    own = _convex_parts(tile.footprint)
    alike = []
    for rival in rival_tiles(tile, shapes):
        theirs = _convex_parts(rival.footprint)
        shared = sum(convex_overlap_area(a, b) for a in own for b in theirs)
        union = abs(signed_area(tile.footprint)) + abs(signed_area(rival.footprint)) - shared
        if union > 0.0 and shared >= share * union:
            alike.append(rival)
    return alike


def _convex_parts(footprint: Array) -> list[Array]:
    """A counter-clockwise footprint as convex counter-clockwise pieces."""
    if is_convex(footprint):
        return [footprint]
    return [footprint[list(corners)] for corners in triangulate(footprint)]


def type_votes(
    scene: VirtualScene,
    index: int,
    rival: PlacedTile,
    image: DepthImage,
    settings: EvidenceSettings,
    ranges: tuple[float, float],
    rival_scene: VirtualScene | None = None,
    cast: VirtualScan | None = None,
) -> TypeVotes:
    """The votes of the depth image between tile `index` of `scene` (S_a) as planned and `rival` in
    its place. `image.window` must cover both tiles; `image.masked` (window-sized) marks robots.
    `rival_scene`: the rival alone, when the caller keeps it from scan to scan; `cast`: `scene`
    cast over `image.window` from `image.pose`, when the caller has it (the scan's own C_v), with
    whatever of its behind layer it looked at."""
    rows, cols = image.window
    planned = cast if cast is not None else scene.cast(image.camera, image.pose, rows, cols, *ranges)
    own = planned.tile == index
    gone = scene.complete_behind(planned, image.camera, image.pose, where=own).behind
    assert gone is not None
    without = np.where(own, gone.depth, planned.depth)
    without_cos = np.where(own, gone.cos_incidence, planned.cos_incidence)
    alone = (rival_scene or VirtualScene([rival])).cast(image.camera, image.pose, rows, cols, *ranges)
    rival_in_front = (alone.tile == 0) & (alone.depth < without)
    swapped = np.where(rival_in_front, alone.depth, without)
    swapped_cos = np.where(rival_in_front, alone.cos_incidence, without_cos)
    measured = image.cloud[rows, cols, 2]
    fits_planned = _fits(measured, planned.depth, planned.cos_incidence, settings)
    fits_swapped = _fits(measured, swapped, swapped_cos, settings)
    steep = math.cos(settings.max_incidence)
    reliable = (
        (own | rival_in_front)
        & smooth(planned.depth) & smooth(swapped)
        & (planned.cos_incidence >= steep) & (swapped_cos >= steep)
    )
    if image.masked is not None:
        reliable &= ~image.masked
    on_rival = reliable & rival_in_front
    fits_gone = _fits(measured, without, without_cos, settings)
    with np.errstate(invalid="ignore"):
        behind_rival = on_rival & ~fits_swapped & (measured > swapped)
    return TypeVotes(
        planned=int(np.count_nonzero(reliable & fits_planned & ~fits_swapped)),
        rival=int(np.count_nonzero(reliable & fits_swapped & ~fits_planned)),
        rival_seen=int(np.count_nonzero(on_rival & fits_swapped & ~fits_gone)),
        rival_missed=int(np.count_nonzero(behind_rival)),
    )


def tiles_box(tiles: Sequence[PlacedTile]) -> tuple[Array, Array]:
    """The axis-aligned box (map frame) holding every one of `tiles`."""
    corners = np.vstack([t.vertices for t in tiles])
    return corners.min(axis=0), corners.max(axis=0)


def _fits(measured: NDArray[np.float32], expected: NDArray[np.float32], cos_incidence: NDArray[np.float32],
          settings: EvidenceSettings) -> Mask:
    """Where a measured depth is the expected surface (no surface expected: nothing fits)."""
    finite = np.isfinite(expected) & np.isfinite(measured)
    tolerance = depth_tolerance(np.where(finite, expected, 1.0), cos_incidence, settings)
    with np.errstate(invalid="ignore"):
        return finite & (np.abs(np.where(finite, measured - expected, np.inf)) <= tolerance)


def _height(shape: TileShape) -> float:
    z = shape.vertices[:, 2]
    return float(z.max() - z.min())
