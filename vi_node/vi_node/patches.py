"""The expected structure S_a as planar patches with an AABB hierarchy (paper section 2.2.1).

"Internally, S_a is represented as a set of planar patches, describing the geometry of the tiles
t_i. Storing the tiles of S_a together with a hierarchy of axis aligned bounding boxes (AABB)
allows for fast computation of the projections of C_1 onto S_a ... we store an AABB for the
structure S_a, for each tile t_i in S_a and each planar patch p in t_i."

A patch is a convex planar polygon: a tile face, or a triangle of a non-convex face. Projecting a
point finds its closest point on S_a: boxes that cannot hold a closer patch are skipped level by
level (structure, tile, patch), and patches that face away from the camera are skipped (the camera
cannot have measured a point on them, e.g. the bottom of a tile resting on another one). The tile
geometry comes from the core (`PlacedTile`).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile, turn_symmetry

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Projection:
    """Closest points of query points on S_a (within the distance asked for)."""

    closest: Array  # (N, 3) closest point on S_a (the query point itself where none was found)
    normal: Array  # (N, 3) outward normal of the patch it lies on
    tile: NDArray[np.int64]  # (N,) index into PlanarPatches.tile_ids, -1 where nothing is close enough
    patch: NDArray[np.int64]  # (N,) index of the patch, -1 where nothing is close enough
    distance: Array  # (N,) distance to the closest point (inf where nothing is close enough)

    @property
    def found(self) -> NDArray[np.bool_]:
        return self.tile >= 0


@dataclass(frozen=True)
class _Patch:
    tile: int
    face: int
    normal: Array
    offset: float
    origin: Array  # a corner; in-plane axes u, v span the polygon
    axes: Array  # (2, 3): u, v
    corners_2d: Array  # (K, 2) counter-clockwise
    edge_normals: Array  # (K, 2) inward unit normals of the edges
    edge_offsets: Array  # (K,) inside when edge_normals . x >= edge_offsets
    edges_2d: Array  # (K, 2) from each corner to the next
    edge_squares: Array  # (K,) squared lengths of the edges
    low: Array
    high: Array


def _is_convex(polygon: Array) -> bool:
    edges = np.roll(polygon, -1, axis=0) - polygon
    cross = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
    return bool(np.all(cross >= -1e-12) or np.all(cross <= 1e-12))


def _make_patch(tile: int, face: int, corners: Array, normal: Array) -> _Patch:
    origin = corners[0]
    u = corners[1] - origin
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    flat = np.column_stack([(corners - origin) @ u, (corners - origin) @ v])
    area = 0.5 * np.sum(flat[:, 0] * np.roll(flat[:, 1], -1) - np.roll(flat[:, 0], -1) * flat[:, 1])
    if area < 0:
        flat = flat[::-1].copy()
    edges = np.roll(flat, -1, axis=0) - flat
    inward = np.column_stack([-edges[:, 1], edges[:, 0]])
    inward /= np.linalg.norm(inward, axis=1, keepdims=True)
    return _Patch(
        tile=tile,
        face=face,
        normal=normal,
        offset=float(normal @ origin),
        origin=origin,
        axes=np.array([u, v]),
        corners_2d=flat,
        edge_normals=inward,
        edge_offsets=np.einsum("ij,ij->i", inward, flat),
        edges_2d=edges,
        edge_squares=np.einsum("ij,ij->i", edges, edges),
        low=corners.min(axis=0),
        high=corners.max(axis=0),
    )


class PlanarPatches:
    """S_a as convex planar patches under a structure -> tile -> patch AABB hierarchy."""

    def __init__(self, tiles: Sequence[PlacedTile]) -> None:
        self.tile_ids = np.array([t.tile_id for t in tiles], dtype=np.int64)
        self.patches: list[_Patch] = []
        self.tile_patches: list[list[int]] = []
        for index, tile in enumerate(tiles):
            mine: list[int] = []
            triangles, face_of = tile.triangles
            for k, normal in enumerate(tile.face_normals):
                corners = tile.face_corners(k)
                u = corners[1] - corners[0]
                flat = np.column_stack(
                    [(corners - corners[0]) @ u, (corners - corners[0]) @ np.cross(normal, u)]
                )
                if _is_convex(flat):
                    pieces = [corners]
                else:
                    pieces = [tile.vertices[tri] for tri in triangles[face_of == k]]
                for piece in pieces:
                    mine.append(len(self.patches))
                    self.patches.append(_make_patch(index, k, piece, normal))
            self.tile_patches.append(mine)
        if tiles:
            self.tile_low = np.array([t.aabb[0] for t in tiles])
            self.tile_high = np.array([t.aabb[1] for t in tiles])
            self.low, self.high = self.tile_low.min(axis=0), self.tile_high.max(axis=0)
        else:
            self.tile_low = self.tile_high = np.zeros((0, 3))
            self.low = self.high = np.zeros(3)
        self.patch_tile = np.array([p.tile for p in self.patches], dtype=np.int64)
        self.tile_centroid = np.array([t.centroid for t in tiles]) if tiles else np.zeros((0, 3))
        self.tile_symmetry = [turn_symmetry(t) for t in tiles]
        self.patch_face = np.array([p.face for p in self.patches], dtype=np.int64)

    def __len__(self) -> int:
        return len(self.tile_ids)

    def project(
        self,
        points: Array,
        max_distance: float,
        camera_position: Array | None = None,
        only_tile: int | None = None,
    ) -> Projection:
        """Closest point on S_a of every point, if one lies within `max_distance`.

        With `camera_position`, patches facing away from the camera are left out. With `only_tile`
        (an index into tile_ids), only that tile's patches are considered.
        """
        n = len(points)
        best = np.full(n, np.inf)
        closest = points.astype(np.float64, copy=True)
        normal = np.zeros((n, 3))
        patch_of = np.full(n, -1, dtype=np.int64)
        pad = max_distance
        in_structure = (
            np.flatnonzero(np.all((points >= self.low - pad) & (points <= self.high + pad), axis=1))
            if len(self)
            else np.zeros(0, dtype=np.int64)
        )
        tiles = range(len(self)) if only_tile is None else [only_tile]
        for t in tiles:
            sub = points[in_structure]
            in_tile = in_structure[
                np.all((sub >= self.tile_low[t] - pad) & (sub <= self.tile_high[t] + pad), axis=1)
            ]
            if len(in_tile) == 0:
                continue
            for index in self.tile_patches[t]:
                patch = self.patches[index]
                if camera_position is not None and patch.normal @ camera_position - patch.offset <= 0:
                    continue
                q = points[in_tile]
                near = np.all((q >= patch.low - pad) & (q <= patch.high + pad), axis=1)
                if not near.any():
                    continue
                ids = in_tile[near]
                foot, distance = self._closest_on_patch(patch, points[ids])
                better = distance < np.minimum(best[ids], max_distance)
                if better.any():
                    chosen = ids[better]
                    best[chosen] = distance[better]
                    closest[chosen] = foot[better]
                    normal[chosen] = patch.normal
                    patch_of[chosen] = index
        tile_of = (
            np.where(patch_of >= 0, self.patch_tile[np.maximum(patch_of, 0)], -1)
            if len(self.patches)
            else patch_of
        )
        return Projection(closest, normal, tile_of, patch_of, best)

    @staticmethod
    def _closest_on_patch(patch: _Patch, points: Array) -> tuple[Array, Array]:
        """Closest points on a convex planar polygon and their distances."""
        relative = points - patch.origin
        height = relative @ patch.normal
        flat = relative @ patch.axes.T  # (M, 2)
        inside = np.all(flat @ patch.edge_normals.T >= patch.edge_offsets - 1e-12, axis=1)
        foot_2d = flat.copy()
        outside = ~inside
        if outside.any():
            q = flat[outside][:, None, :]  # (m, 1, 2)
            a = patch.corners_2d[None, :, :]
            edge = patch.edges_2d[None, :, :]
            t = np.clip(np.sum((q - a) * edge, axis=2) / patch.edge_squares[None, :], 0.0, 1.0)
            on_edge = a + t[..., None] * edge  # (m, K, 2)
            gap = np.sum((q - on_edge) ** 2, axis=2)
            nearest = np.argmin(gap, axis=1)
            foot_2d[outside] = on_edge[np.arange(len(nearest)), nearest]
        in_plane = np.sum((flat - foot_2d) ** 2, axis=1)
        foot = patch.origin + foot_2d @ patch.axes
        return foot, np.sqrt(height**2 + in_plane)
