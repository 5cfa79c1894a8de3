"""Ray tracing of the virtual Kinect K_v through S_a (paper section 2.2.2).

"We position the virtual Kinect at pose P_v and simulate a ray-tracing using the Kinect's optical
properties (resolution, view angles) ... For each ray, we compute the closest intersection with a
tile t_i ... For each point in C_v, we know the supported tile t_i."

S_a (and the floor, which hides what is below it and stops rays) is an Open3D ray casting scene
(itself a BVH), built once per S_a and reused for every scan while S_a is unchanged. Only the
rays of the pixels that can see S_a's bounding box are cast. The same scene, without the floor,
answers closest-point queries for the alignment (a faster stand-in for the patch hierarchy).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile
from tiling_assembly.open3d_loader import import_open3d
from vi_node.camera_model import PinholeCamera

Array = NDArray[np.float64]

FLOOR = -1  # VirtualScan.tile value of pixels that see the floor
NOTHING = -2  # ... and of pixels whose ray hits nothing (or is outside the sensor's range)


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

    def support(self, tile_count: int) -> NDArray[np.int64]:
        """v_i: the number of virtual points on every tile."""
        hits = self.tile[self.tile >= 0]
        return np.bincount(hits, minlength=tile_count).astype(np.int64)


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
        self.has_tiles = bool(tiles)
        self._tiles = list(tiles)
        self._tile_scenes: dict[int, object] = {}  # built on demand, for refitting single tiles

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
        rays = np.empty((*directions.shape[:2], 6), dtype=np.float32)
        rays[..., :3] = pose[:3, 3]
        rays[..., 3:] = directions
        result = self.ray_scene.cast_rays(self._core.Tensor.from_numpy(rays))
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
        tile[(geometry == self.floor_geometry) & in_range] = FLOOR
        cosine = np.zeros(depth.shape, dtype=np.float32)
        d, n = directions[hit], normals[hit]
        cosine[hit] = np.abs(np.einsum("ij,ij->i", d, n)) / np.sqrt(np.einsum("ij,ij->i", d, d))
        depth = np.where(in_range, depth, np.float32(np.inf))
        return VirtualScan(rows, cols, depth, tile, face, cosine, (camera.width, camera.height))

    def closest_on_tile(self, points: Array, index: int) -> tuple[Array, Array]:
        """Closest points on tile `index` (of the scene's tiles) alone, and the normals there."""
        scene = self._tile_scenes.get(index)
        if scene is None:
            o3d = import_open3d()
            tile = self._tiles[index]
            triangles, _ = tile.triangles
            scene = o3d.t.geometry.RaycastingScene()
            scene.add_triangles(
                self._core.Tensor(tile.vertices.astype(np.float32)),
                self._core.Tensor(triangles.astype(np.uint32)),
            )
            self._tile_scenes[index] = scene
        result = scene.compute_closest_points(  # type: ignore[attr-defined]
            self._core.Tensor.from_numpy(np.ascontiguousarray(points, dtype=np.float32))
        )
        return result["points"].numpy().astype(np.float64), result["primitive_normals"].numpy().astype(
            np.float64
        )

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
