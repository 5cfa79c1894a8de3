"""Which tiles touch, overlap or rest on each other (paper section 2.1: the tiling's graph).

Two tiles *touch* when their surfaces come within `contact_tolerance`; they *overlap* when they
interpenetrate by more than `overlap_tolerance` along every separating-axis candidate. Tile j
*supports* tile i when an upward-facing face of j and a downward-facing face of i lie in the same
plane and share more than `min_support_area`. A broad phase (spatial hashing of axis-aligned
boxes) keeps this near-linear for structures of thousands of tiles, and pairs of box tiles (most
tiles of big structures) are decided as arrays, all at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly import polygons
from tiling_assembly.geometry import PieceAxes, PlacedTile, place_together

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

CONTACT_TOLERANCE = 1e-3  # m: surfaces closer than this touch
OVERLAP_TOLERANCE = 1e-3  # m: interpenetration deeper than this is an overlap
MIN_SUPPORT_AREA = 1e-4  # m^2: shared area for one tile to rest on another (1 cm^2)
MIN_SLOPE_NORMAL_Z = 0.1  # faces steeper than this (|n_z| below it) are sides, not supports


@dataclass(frozen=True)
class Contacts:
    """Pairs of tiles whose surfaces meet, as arrays (a 10k-tile structure has 76k of them): by
    tile id (a < b) and by index in the tile list, with their signed separations."""

    a: IntArray  # (P,) the lower id of each pair
    b: IntArray  # (P,) the higher id
    a_index: IntArray  # (P,) index of tile `a` in the tile list
    b_index: IntArray
    separation: Array  # (P,) m, signed: <= 0 in contact, < -OVERLAP_TOLERANCE overlapping

    def id_pairs(self) -> list[tuple[int, int]]:
        return list(zip(self.a.tolist(), self.b.tolist(), strict=True))


@dataclass(frozen=True)
class Boxes:
    """The tiles' axis-aligned bounding boxes as arrays, in the order of the tile list, and which
    tiles are exactly their box (an axis-aligned box tile: every test on it is a test on arrays)."""

    lo: Array  # (N, 3)
    hi: Array  # (N, 3)
    exact: NDArray[np.bool_]  # (N,)

    @classmethod
    def of(cls, tiles: list[PlacedTile]) -> Boxes:
        place_together(tiles)
        lo = np.array([t.aabb[0] for t in tiles]).reshape(-1, 3)
        hi = np.array([t.aabb[1] for t in tiles]).reshape(-1, 3)
        box = np.prod(hi - lo, axis=1)
        volume = np.array([t.volume for t in tiles])
        return cls(lo, hi, np.abs(box - volume) <= 1e-9 + 1e-6 * box)


def candidate_pairs(tiles: list[PlacedTile], margin: float, boxes: Boxes | None = None) -> list[tuple[int, int]]:
    """Index pairs (i < j) whose bounding boxes, grown by `margin`, intersect.

    Spatial hashing: the cells are as large as the largest box, so that a box covers at most two
    cells along each axis; boxes sharing a cell are the candidates, tested as arrays. The pairs
    come in the order of a sort and sweep on x (by the x-rank of the pair's first box, then of its
    second), the order the structure's contacts and rule violations have always been reported in.
    """
    first, second = _candidate_index_pairs(boxes or Boxes.of(tiles), margin)
    return list(zip(first.tolist(), second.tolist(), strict=True))


def _candidate_index_pairs(boxes: Boxes, margin: float) -> tuple[IntArray, IntArray]:
    """`candidate_pairs` as two arrays (first < second)."""
    if len(boxes.lo) < 2:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    lo, hi = boxes.lo - margin, boxes.hi + margin
    first, second = _sharing_a_cell(lo, hi)
    hit = np.all((lo[first] <= hi[second]) & (hi[first] >= lo[second]), axis=1)
    count = len(lo)
    sweep_order = np.argsort(lo[:, 0], kind="stable")
    rank = np.empty(count, dtype=np.int64)
    rank[sweep_order] = np.arange(count)
    first_rank, second_rank = rank[first[hit]], rank[second[hit]]
    # one integer per pair, ordered as the sweep meets the pairs; repeats (several shared cells) merge
    sweep_keys = np.unique(np.minimum(first_rank, second_rank) * count + np.maximum(first_rank, second_rank))
    a, b = sweep_order[sweep_keys // count], sweep_order[sweep_keys % count]
    return np.minimum(a, b), np.maximum(a, b)


def _sharing_a_cell(lo: Array, hi: Array) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(i, j) with i < j for every cell two boxes share (a pair may repeat)."""
    size = np.maximum((hi - lo).max(axis=0), 1e-6)
    first_cell = np.floor((lo - lo.min(axis=0)) / size).astype(np.int64)
    last_cell = np.floor((hi - lo.min(axis=0)) / size).astype(np.int64)
    steps = np.array([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.int64)
    cells = first_cell[:, None, :] + steps[None, :, :]  # (N, 8, 3): each box's cells, some twice
    inside = np.all(cells <= last_cell[:, None, :], axis=2)
    owner = np.repeat(np.arange(len(lo)), 8)[inside.ravel()]
    keys = _cell_keys(cells[inside], last_cell.max(axis=0) + 2)
    by_cell = np.lexsort((owner, keys))
    keys, owner = keys[by_cell], owner[by_cell]
    group_end = np.searchsorted(keys, keys, side="right")
    followers = group_end - np.arange(len(keys)) - 1
    position = np.repeat(np.arange(len(keys)), followers)
    starts = np.cumsum(followers) - followers
    partner = position + 1 + np.arange(len(position)) - np.repeat(starts, followers)
    return owner[position], owner[partner]


def _cell_keys(cells: NDArray[np.int64], shape: NDArray[np.int64]) -> NDArray[np.int64]:
    """One integer per cell (equal for equal cells)."""
    if float(np.prod(shape.astype(np.float64))) < 2.0**62:
        return np.ravel_multi_index(tuple(cells.T), tuple(shape))
    return np.unique(cells, axis=0, return_inverse=True)[1].ravel()  # far-apart tiles: a sparse grid


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


def separation(a: PlacedTile, b: PlacedTile) -> float:
    """Signed separation of two tiles (see _convex_separation), over all their convex pieces."""
    return min(
        _convex_separation(pa, xa, pb, xb)
        for pa, xa in zip(a.pieces, a.piece_axes, strict=True)
        for pb, xb in zip(b.pieces, b.piece_axes, strict=True)
    )


def find_contacts(
    tiles: list[PlacedTile], contact_tolerance: float = CONTACT_TOLERANCE, boxes: Boxes | None = None
) -> Contacts:
    """Every pair of tiles that touch or overlap. Two box tiles are exactly their bounding boxes,
    so their separation is the boxes' (all such pairs at once)."""
    boxes = boxes or Boxes.of(tiles)
    i, j = _candidate_index_pairs(boxes, contact_tolerance)
    separations = np.maximum(boxes.lo[j] - boxes.hi[i], boxes.lo[i] - boxes.hi[j]).max(axis=1)
    for k in np.flatnonzero(~(boxes.exact[i] & boxes.exact[j])).tolist():
        separations[k] = separation(tiles[i[k]], tiles[j[k]])
    touching = separations <= contact_tolerance
    i, j = i[touching], j[touching]
    ids = np.array([t.tile_id for t in tiles], dtype=np.int64)
    i_first = ids[i] < ids[j]
    a_index, b_index = np.where(i_first, i, j), np.where(i_first, j, i)
    return Contacts(ids[a_index], ids[b_index], a_index, b_index, separations[touching])


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


def resting_pairs(
    tiles: list[PlacedTile], found: Contacts, *, boxes: Boxes, plane_tolerance: float = CONTACT_TOLERANCE,
    min_area: float = MIN_SUPPORT_AREA,
) -> list[tuple[int, int]]:
    """(lower id, upper id) of the touching pairs where an upward face of the lower tile meets a
    downward face of the upper one over more than `min_area` (see `shared_face_area`).

    Two box tiles meet only lower's top to upper's bottom, over the overlap of their x-y rectangles:
    all such pairs at once; the others face by face."""
    ids = np.array([t.tile_id for t in tiles], dtype=np.int64)
    a, b = found.a_index, found.b_index
    both_boxes = boxes.exact[a] & boxes.exact[b]
    sides = np.minimum(boxes.hi[a, :2], boxes.hi[b, :2]) - np.maximum(boxes.lo[a, :2], boxes.lo[b, :2])
    overlapping = both_boxes & (np.prod(np.clip(sides, 0.0, None), axis=1) > min_area)
    a_under_b = overlapping & (np.abs(boxes.hi[a, 2] - boxes.lo[b, 2]) <= plane_tolerance)
    b_under_a = overlapping & (np.abs(boxes.hi[b, 2] - boxes.lo[a, 2]) <= plane_tolerance)
    resting = list(zip(ids[a[a_under_b]].tolist(), ids[b[a_under_b]].tolist(), strict=True))
    resting += zip(ids[b[b_under_a]].tolist(), ids[a[b_under_a]].tolist(), strict=True)
    for k in np.flatnonzero(~both_boxes).tolist():
        lower, upper = tiles[a[k]], tiles[b[k]]
        if shared_face_area(lower, upper, plane_tolerance) > min_area:
            resting.append((lower.tile_id, upper.tile_id))
        if shared_face_area(upper, lower, plane_tolerance) > min_area:
            resting.append((upper.tile_id, lower.tile_id))
    return resting


def on_the_floor(tiles: list[PlacedTile], *, boxes: Boxes, plane_tolerance: float = CONTACT_TOLERANCE,
                 min_area: float = MIN_SUPPORT_AREA) -> set[int]:
    """Ids of the tiles whose downward faces lie on the floor (z = 0) over more than `min_area`."""
    sides = boxes.hi[:, :2] - boxes.lo[:, :2]
    box_on_floor = (np.abs(boxes.lo[:, 2]) <= plane_tolerance) & (sides[:, 0] * sides[:, 1] > min_area)
    return {
        t.tile_id for t, exact, lying in zip(tiles, boxes.exact.tolist(), box_on_floor.tolist(), strict=True)
        if (lying if exact else floor_contact_area(t, plane_tolerance) > min_area)
    }


def floor_contact_area(tile: PlacedTile, plane_tolerance: float = CONTACT_TOLERANCE) -> float:
    """Area of the tile's downward faces lying on the floor (z = 0), in m^2."""
    total = 0.0
    for k, (n, d) in enumerate(zip(tile.face_normals, tile.face_offsets, strict=True)):
        if n[2] < -0.9999 and abs(d) <= plane_tolerance:
            corners = tile.face_corners(k)
            total += abs(polygons.signed_area(corners[:, :2]))
    return total
