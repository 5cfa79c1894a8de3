"""Ray tracing of the virtual Kinect K_v through S_a (paper section 2.2.2).

"We position the virtual Kinect at pose P_v and simulate a ray-tracing using the Kinect's optical
properties (resolution, view angles) ... For each ray, we compute the closest intersection with a
tile t_i ... For each point in C_v, we know the supported tile t_i."

S_a (and the floor, which hides what is below it and stops rays) is an Open3D ray casting scene
(itself a BVH), built once per S_a and reused for every scan while S_a is unchanged. Only the
rays of the pixels that can see S_a's bounding box are cast. The same scene, without the floor,
answers closest-point queries for the alignment (a faster stand-in for the patch hierarchy).

Beyond the paper, for the inspection's second hypothesis ("this tile is gone"): `look_behind`
finds, on every pixel of a tile, the first surface of anything else along the same ray (what the
camera would see with that tile removed), and `blocked` tells whether a straight segment (from
the Kinect's IR projector to a surface point) passes through anything, optionally ignoring one
tile (the projector lights what a removed tile no longer hides).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile
from tiling_assembly.open3d_loader import import_open3d
from vi_node.camera_model import PinholeCamera

Array = NDArray[np.float64]

FLOOR = -1  # VirtualScan.tile value of pixels that see the floor
NOTHING = -2  # ... and of pixels whose ray hits nothing (or is outside the sensor's range)
NO_TILE = -3  # `blocked`: ignore no tile
UNSEEN = -4  # SurfaceLayer.tile of the behind layer on tile pixels not looked behind (depth NaN)
_NO_FACES = object()  # `closest_on_tile`: no face of the tile is turned towards the camera


@dataclass(frozen=True)
class SurfaceLayer:
    """One surface per pixel of an image window: where a ray meets it and how obliquely."""

    depth: NDArray[np.float32]  # (h, w) optical depth z of the hit (inf: none)
    tile: NDArray[np.int64]  # (h, w) index into the scene's tiles, FLOOR or NOTHING
    cos_incidence: NDArray[np.float32]  # (h, w) |cos| of the angle between ray and surface normal


@dataclass(frozen=True)
class VirtualScan:
    """The virtual scan C_v over an image window (rows, cols) of the camera."""

    rows: slice
    cols: slice
    depth: NDArray[np.float32]  # (h, w) optical depth z of the hit (inf: none)
    tile: NDArray[np.int64]  # (h, w) index into the scene's tiles, FLOOR or NOTHING
    face: NDArray[np.int64]  # (h, w) face of that tile (-1 elsewhere)
    cos_incidence: NDArray[np.float32]  # (h, w) |cos| of the angle between ray and surface normal
    size: tuple[int, int]  # (width, height) of the whole image
    behind: SurfaceLayer | None = None  # on tile pixels: the first surface of anything but that tile

    def support(self, tile_count: int) -> NDArray[np.int64]:
        """v_i: the number of virtual points on every tile."""
        hits = self.tile[self.tile >= 0]
        return np.bincount(hits, minlength=tile_count).astype(np.int64)

    @property
    def front(self) -> SurfaceLayer:
        return SurfaceLayer(self.depth, self.tile, self.cos_incidence)

    def within(self, rows: slice, cols: slice) -> VirtualScan | None:
        """This scan over the image window (rows, cols), behind layer included, or None when that
        window reaches beyond this scan's (a ray's hit does not depend on the window it is cast in)."""
        if not (self.rows.start <= rows.start <= rows.stop <= self.rows.stop
                and self.cols.start <= cols.start <= cols.stop <= self.cols.stop):
            return None
        r = slice(rows.start - self.rows.start, rows.stop - self.rows.start)
        c = slice(cols.start - self.cols.start, cols.stop - self.cols.start)
        behind = self.behind
        if behind is not None:
            behind = SurfaceLayer(behind.depth[r, c], behind.tile[r, c], behind.cos_incidence[r, c])
        return VirtualScan(rows, cols, self.depth[r, c], self.tile[r, c], self.face[r, c],
                           self.cos_incidence[r, c], self.size, behind)


class VirtualScene:
    """S_a (plus the floor) ready for ray casting and closest-point queries."""

    def __init__(self, tiles: Sequence[PlacedTile], floor_half_size: float = 30.0) -> None:
        o3d = import_open3d()
        self._core = o3d.core
        self.tile_ids = np.array([t.tile_id for t in tiles], dtype=np.int64)
        vertices, triangles, tri_tile, tri_face = [], [], [], []
        offset = 0
        for index, tile in enumerate(tiles):
            tris, face_of = tile.triangles
            vertices.append(tile.vertices)
            triangles.append(tris + offset)
            tri_tile.append(np.full(len(tris), index))
            tri_face.append(face_of)
            offset += len(tile.vertices)
        self.ray_scene = o3d.t.geometry.RaycastingScene()
        self.closest_scene = o3d.t.geometry.RaycastingScene()
        self.structure_geometry = -1
        if tiles:
            v = self._core.Tensor(np.vstack(vertices).astype(np.float32))
            t = self._core.Tensor(np.vstack(triangles).astype(np.uint32))
            self.structure_geometry = self.ray_scene.add_triangles(v, t)
            self.closest_scene.add_triangles(v, t)
        h = floor_half_size
        self.floor_geometry = self.ray_scene.add_triangles(
            self._core.Tensor(np.array([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]], dtype=np.float32)),
            self._core.Tensor(np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)),
        )
        self.triangle_tile = np.concatenate(tri_tile).astype(np.int64) if tiles else np.zeros(0, np.int64)
        self.triangle_face = np.concatenate(tri_face).astype(np.int64) if tiles else np.zeros(0, np.int64)
        if tiles:
            corners = np.vstack(vertices)[np.vstack(triangles)]
            normal = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
            self.triangle_normal = normal / np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-12)
        else:
            self.triangle_normal = np.zeros((0, 3))
        self.has_tiles = bool(tiles)
        self._tiles = list(tiles)
        self._tile_scenes: dict[tuple[int, tuple[int, ...] | None], object] = {}  # built on demand, for
        # refitting single tiles: per tile and faces turned towards the camera

    def _rays(self, origin: Array, directions: NDArray[np.float32]) -> object:
        rays = np.empty((*directions.shape[:-1], 6), dtype=np.float32)
        rays[..., :3] = origin
        rays[..., 3:] = directions
        return self._core.Tensor.from_numpy(rays)

    def cast(
        self,
        camera: PinholeCamera,
        pose: Array,
        rows: slice,
        cols: slice,
        min_range: float = 0.0,
        max_range: float = np.inf,
    ) -> VirtualScan:
        """Cast the pixels (rows, cols) of a camera at `pose` (4x4 optical frame in map)."""
        directions = camera.rays[rows, cols] @ pose[:3, :3].T.astype(np.float32)
        result = self.ray_scene.cast_rays(self._rays(pose[:3, 3], directions))
        depth = result["t_hit"].numpy()  # rays have z = 1 in the optical frame: t is the depth
        geometry = result["geometry_ids"].numpy()
        primitive = result["primitive_ids"].numpy().astype(np.int64)
        normals = result["primitive_normals"].numpy()
        on_structure = geometry == self.structure_geometry
        in_range = (depth >= min_range) & (depth <= max_range)
        tile = np.full(depth.shape, NOTHING, dtype=np.int64)
        face = np.full(depth.shape, -1, dtype=np.int64)
        hit = on_structure & in_range
        tile[hit] = self.triangle_tile[primitive[hit]]
        face[hit] = self.triangle_face[primitive[hit]]
        floor = (geometry == self.floor_geometry) & in_range
        tile[floor] = FLOOR
        cosine = np.zeros(depth.shape, dtype=np.float32)
        seen = hit | floor
        cosine[seen] = _cosine(directions[seen], normals[seen])
        depth = np.where(in_range, depth, np.float32(np.inf))
        return VirtualScan(rows, cols, depth, tile, face, cosine, (camera.width, camera.height))

    def look_behind(
        self, virtual: VirtualScan, camera: PinholeCamera, pose: Array, where: NDArray[np.bool_] | None = None
    ) -> VirtualScan:
        """`virtual` with its `behind` layer: on every tile pixel (of `where`, window-sized), the
        first surface along the ray that belongs to anything but that pixel's tile (another tile,
        the floor, or nothing), as the camera would see it with that tile gone; UNSEEN (depth
        NaN) on the other tile pixels. Off the tiles the layer repeats the front one."""
        wanted = virtual.tile >= 0 if where is None else (virtual.tile >= 0) & where
        on_tile = np.flatnonzero(wanted.reshape(-1))
        unseen = (virtual.tile >= 0) & ~wanted
        depth = np.where(unseen, np.float32(np.nan), virtual.depth)
        tile = np.where(unseen, UNSEEN, virtual.tile)
        cosine = np.where(unseen, np.float32(0.0), virtual.cos_incidence)
        if len(on_tile):
            directions = (camera.rays[virtual.rows, virtual.cols].reshape(-1, 3)[on_tile]) @ pose[
                :3, :3
            ].T.astype(np.float32)
            own = virtual.tile.reshape(-1)[on_tile]
            first = self._first_hits(pose[:3, 3], directions, own, np.full(len(on_tile), np.inf))
            flat_depth, flat_tile, flat_cos = depth.reshape(-1), tile.reshape(-1), cosine.reshape(-1)
            flat_depth[on_tile] = first.depth
            flat_tile[on_tile] = first.tile
            flat_cos[on_tile] = _cosine(directions, first.normal)
        return replace(virtual, behind=SurfaceLayer(depth, tile, cosine))

    def complete_behind(
        self, virtual: VirtualScan, camera: PinholeCamera, pose: Array, where: NDArray[np.bool_]
    ) -> VirtualScan:
        """`virtual` with its `behind` layer also on the tile pixels of `where`, keeping what it holds
        (`virtual` itself when nothing is missing)."""
        known = virtual.behind
        missing = where if known is None else where & (known.tile == UNSEEN)
        if known is not None and not missing.any():
            return virtual
        fresh = self.look_behind(virtual, camera, pose, where=missing).behind
        assert fresh is not None
        if known is None:
            return replace(virtual, behind=fresh)
        return replace(virtual, behind=SurfaceLayer(
            np.where(missing, fresh.depth, known.depth),
            np.where(missing, fresh.tile, known.tile),
            np.where(missing, fresh.cos_incidence, known.cos_incidence),
        ))

    def blocked(
        self, start: Array, ends: Array, ignore: NDArray[np.int64] | None = None, margin: float = 0.004
    ) -> NDArray[np.bool_]:
        """Whether the segment from `start` (3,) to each of `ends` (N, 3) meets a surface before
        `margin` (m) short of its end; surfaces of tile `ignore[k]` (scene index; NO_TILE: none) do
        not count for segment k."""
        if len(ends) == 0:
            return np.zeros(0, dtype=bool)
        span = ends - start
        length = np.sqrt(np.einsum("ij,ij->i", span, span))
        directions = (span * (1.0 - margin / np.maximum(length, margin * 2))[:, None]).astype(np.float32)
        if ignore is None or not np.any(ignore != NO_TILE):
            hit = self.ray_scene.test_occlusions(self._rays(start, directions), tnear=0.0, tfar=1.0)
            return hit.numpy().astype(bool)
        first = self._first_hits(start, directions, ignore, np.ones(len(ends)))
        return np.isfinite(first.depth)

    def _first_hits(
        self, origin: Array, directions: NDArray[np.float32], ignore: NDArray[np.int64], limit: Array
    ) -> _Hits:
        """First hit along each ray up to t = limit that is not on tile `ignore[k]`."""
        result = self.ray_scene.list_intersections(self._rays(origin, directions))
        splits = result["ray_splits"].numpy().astype(np.int64)
        t = result["t_hit"].numpy()
        geometry = result["geometry_ids"].numpy()
        primitive = result["primitive_ids"].numpy().astype(np.int64)
        count = len(directions)
        ray = np.repeat(np.arange(count), np.diff(splits))
        on_structure = geometry == self.structure_geometry
        owner = np.full(len(t), NOTHING, dtype=np.int64)
        owner[on_structure] = self.triangle_tile[primitive[on_structure]]
        owner[geometry == self.floor_geometry] = FLOOR
        keep = (owner != ignore[ray]) & (owner != NOTHING) & (t <= limit[ray])
        candidate = np.where(keep, t, np.inf).astype(np.float32)
        depth = np.full(count, np.inf, dtype=np.float32)
        some = splits[1:] > splits[:-1]
        depth[some] = np.minimum.reduceat(candidate, splits[:-1][some]) if len(candidate) else depth[some]
        first = keep & (candidate == depth[ray])
        chosen, index = np.unique(ray[first], return_index=True)  # one hit per ray where several tie
        hit = np.flatnonzero(first)[index]
        tile = np.full(count, NOTHING, dtype=np.int64)
        tile[chosen] = owner[hit]
        normal = np.zeros((count, 3), dtype=np.float64)
        structure = owner[hit] >= 0
        normal[chosen[structure]] = self.triangle_normal[primitive[hit][structure]]
        normal[chosen[~structure]] = (0.0, 0.0, 1.0)
        return _Hits(depth, tile, normal)

    def closest_on_tile(
        self, points: Array, index: int, camera_position: Array | None = None
    ) -> tuple[Array, Array]:
        """Closest points on tile `index` (of the scene's tiles) alone, and the normals there. With
        `camera_position`, on the faces turned towards it only: a camera measures no point on the
        others (none turned towards it: closest points at infinity)."""
        tile = self._tiles[index]
        faces = None
        if camera_position is not None:
            faces = tuple(np.flatnonzero(tile.face_normals @ camera_position - tile.face_offsets > 0).tolist())
        scene = self._tile_scenes.get((index, faces))
        if scene is None:
            scene = self._tile_scene(tile, faces)
            self._tile_scenes[(index, faces)] = scene
        if scene is _NO_FACES:
            return np.full((len(points), 3), np.inf), np.zeros((len(points), 3))
        result = scene.compute_closest_points(  # type: ignore[attr-defined]
            self._core.Tensor.from_numpy(np.ascontiguousarray(points, dtype=np.float32))
        )
        return result["points"].numpy().astype(np.float64), result["primitive_normals"].numpy().astype(
            np.float64
        )

    def _tile_scene(self, tile: PlacedTile, faces: tuple[int, ...] | None) -> object:
        """A scene of `tile`'s triangles (on `faces` only, if given), for closest points."""
        triangles, face_of = tile.triangles
        if faces is not None:
            triangles = triangles[np.isin(face_of, faces)]
        if len(triangles) == 0:
            return _NO_FACES
        scene = import_open3d().t.geometry.RaycastingScene()
        scene.add_triangles(
            self._core.Tensor(tile.vertices.astype(np.float32)),
            self._core.Tensor(triangles.astype(np.uint32)),
        )
        return scene

    def closest_points(self, points: Array) -> tuple[Array, Array, NDArray[np.int64]]:
        """Closest point on S_a, the normal there and the tile index, for every point."""
        result = self.closest_scene.compute_closest_points(
            self._core.Tensor.from_numpy(np.ascontiguousarray(points, dtype=np.float32))
        )
        primitive = result["primitive_ids"].numpy().astype(np.int64)
        return (
            result["points"].numpy().astype(np.float64),
            result["primitive_normals"].numpy().astype(np.float64),
            self.triangle_tile[primitive],
        )


@dataclass(frozen=True)
class _Hits:
    depth: NDArray[np.float32]  # t of the hit (inf: none)
    tile: NDArray[np.int64]  # tile index, FLOOR or NOTHING
    normal: Array  # (N, 3) unit normal of the surface hit (zeros: none)


def _cosine(directions: NDArray[np.float32], normals: Array) -> NDArray[np.float32]:
    """|cos| of the angle between rays and surface normals (0 where the normal is zero)."""
    length = np.sqrt(np.einsum("ij,ij->i", directions, directions))
    return (np.abs(np.einsum("ij,ij->i", directions, normals)) / np.maximum(length, 1e-12)).astype(np.float32)
