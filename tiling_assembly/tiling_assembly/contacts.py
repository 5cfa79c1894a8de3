"""Which tiles touch, overlap or rest on each other (paper section 2.1: the tiling's graph).

Two tiles *touch* when their surfaces come within `contact_tolerance`; they *overlap* when they
interpenetrate by more than `overlap_tolerance` along every separating-axis candidate. Tile j
*supports* tile i when an upward-facing face of j and a downward-facing face of i lie in the same
plane and share more than `min_support_area`. A broad phase (sort and sweep over axis-aligned
boxes) keeps this near-linear for structures of thousands of tiles.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly import polygons
from tiling_assembly.geometry import PieceAxes, PlacedTile

Array = NDArray[np.float64]

CONTACT_TOLERANCE = 1e-3  # m: surfaces closer than this touch
OVERLAP_TOLERANCE = 1e-3  # m: interpenetration deeper than this is an overlap
MIN_SUPPORT_AREA = 1e-4  # m^2: shared area for one tile to rest on another (1 cm^2)
MIN_SLOPE_NORMAL_Z = 0.1  # faces steeper than this (|n_z| below it) are sides, not supports


@dataclass(frozen=True)
class Contact:
    """Two tiles whose surfaces meet (a < b)."""

    a: int
    b: int
    separation: float  # m, signed: <= 0 in contact, < -OVERLAP_TOLERANCE overlapping


def candidate_pairs(tiles: list[PlacedTile], margin: float) -> list[tuple[int, int]]:
    """Index pairs whose bounding boxes, grown by `margin`, intersect (sort and sweep on x)."""
    if len(tiles) < 2:
        return []
    lo = np.array([t.aabb[0] for t in tiles]) - margin
    hi = np.array([t.aabb[1] for t in tiles]) + margin
    order = np.argsort(lo[:, 0], kind="stable")
    lo_sorted, hi_sorted = lo[order], hi[order]
    # for each box, the sorted boxes that start before it ends
    ends = np.searchsorted(lo_sorted[:, 0], hi_sorted[:, 0], side="right")
    pairs: list[tuple[int, int]] = []
    for k in range(len(tiles)):
        others = np.arange(k + 1, ends[k])
        if len(others) == 0:
            continue
        hit = np.all(
            (lo_sorted[others, 1:] <= hi_sorted[k, 1:]) & (hi_sorted[others, 1:] >= lo_sorted[k, 1:]),
            axis=1,
        )
        a = order[k]
        for b in order[others[hit]]:
            pairs.append((int(min(a, b)), int(max(a, b))))
    return pairs


def _convex_separation(va: Array, axes_a: PieceAxes, vb: Array, axes_b: PieceAxes) -> float:
    """Largest gap between the projections of two convex pieces over the separating axes.

    Positive: the pieces are at least that far apart. Negative: they interpenetrate by at least
    its magnitude along every candidate axis (the penetration depth).
    """
    crosses = np.cross(axes_a.edges[:, None, :], axes_b.edges[None, :, :]).reshape(-1, 3)
    norms = np.linalg.norm(crosses, axis=1)
    crosses = crosses[norms > 1e-9] / norms[norms > 1e-9, None]
    axes = np.vstack([axes_a.normals, axes_b.normals, crosses])
    pa, pb = va @ axes.T, vb @ axes.T
    gaps = np.maximum(pb.min(axis=0) - pa.max(axis=0), pa.min(axis=0) - pb.max(axis=0))
    return float(gaps.max())


def _fills_its_box(tile: PlacedTile) -> bool:
    """Whether the tile is an axis-aligned box, so that its bounding box is exact."""
    lo, hi = tile.aabb
    box = float(np.prod(hi - lo))
    return abs(box - tile.volume) <= 1e-9 + 1e-6 * box


def separation(a: PlacedTile, b: PlacedTile) -> float:
    """Signed separation of two tiles (see _convex_separation), over all their convex pieces."""
    if _fills_its_box(a) and _fills_its_box(b):  # axis-aligned boxes: the boxes are exact
        gaps = np.maximum(b.aabb[0] - a.aabb[1], a.aabb[0] - b.aabb[1])
        return float(gaps.max())
    return min(
        _convex_separation(pa, xa, pb, xb)
        for pa, xa in zip(a.pieces, a.piece_axes, strict=True)
        for pb, xb in zip(b.pieces, b.piece_axes, strict=True)
    )


def find_contacts(
    tiles: list[PlacedTile], contact_tolerance: float = CONTACT_TOLERANCE
) -> list[Contact]:
    """Every pair of tiles that touch or overlap, by tile id."""
    contacts = []
    for i, j in candidate_pairs(tiles, contact_tolerance):
        sep = separation(tiles[i], tiles[j])
        if sep <= contact_tolerance:
            a, b = sorted((tiles[i].tile_id, tiles[j].tile_id))
            contacts.append(Contact(a, b, sep))
    return contacts


def plane_basis(normal: Array) -> tuple[Array, Array]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(normal, helper)
    u /= np.linalg.norm(u)
    return u, np.cross(normal, u)


def _face_pieces_2d(tile: PlacedTile, face: int, u: Array, v: Array) -> list[Array]:
    """Convex counter-clockwise 2-D pieces of a face, in the plane basis (u, v)."""
    corners = tile.face_corners(face)
    flat = polygons.counter_clockwise(np.column_stack([corners @ u, corners @ v]))
    if polygons.is_convex(flat):
        return [flat]
    return [flat[list(t)] for t in polygons.triangulate(flat)]


def shared_face_area(
    lower: PlacedTile, upper: PlacedTile, plane_tolerance: float = CONTACT_TOLERANCE
) -> float:
    """Area over which an upward face of `lower` meets a downward face of `upper` (m^2)."""
    if lower.aabb[1][2] < upper.aabb[0][2] - plane_tolerance:
        return 0.0  # lower's top is below upper's bottom: no face can meet
    # face pairs that lie in one plane with opposite normals, lower's facing up
    facing = lower.face_normals @ upper.face_normals.T < -0.9999
    same_plane = np.abs(lower.face_offsets[:, None] + upper.face_offsets[None, :]) <= plane_tolerance
    upward = (lower.face_normals[:, 2] >= MIN_SLOPE_NORMAL_Z)[:, None]
    total = 0.0
    for fa, fb in zip(*np.nonzero(facing & same_plane & upward), strict=True):
        pieces_a, pieces_b = lower.flat_face_pieces[fa], upper.flat_face_pieces[fb]
        if pieces_a is None or pieces_b is None:  # a sloped contact: work in its plane
            u, v = plane_basis(lower.face_normals[fa])
            pieces_a, pieces_b = _face_pieces_2d(lower, int(fa), u, v), _face_pieces_2d(upper, int(fb), u, v)
        for pa in pieces_a:
            for pb in pieces_b:
                total += polygons.convex_overlap_area(pa, pb)
    return total


def floor_contact_area(tile: PlacedTile, plane_tolerance: float = CONTACT_TOLERANCE) -> float:
    """Area of the tile's downward faces lying on the floor (z = 0), in m^2."""
    total = 0.0
    for k, (n, d) in enumerate(zip(tile.face_normals, tile.face_offsets, strict=True)):
        if n[2] < -0.9999 and abs(d) <= plane_tolerance:
            corners = tile.face_corners(k)
            total += abs(polygons.signed_area(corners[:, :2]))
    return total
