"""Kinect v1 depth simulator: ray cast what is physically there, then apply the sensor's noise.

The simulated counterpart of the physical Kinect K_p of paper section 2.2 (DESIGN.md "Simulate").
Sensor facts (HARDWARE.md): 640x480 at fx = fy = 580 px (57 x 45 degree field of view), range
0.5-4.5 m; axial noise sigma_z = 0.0012 + 0.0019 (z - 0.4)^2 m up to 60 degree incidence, plus
0.0001/sqrt(z) * theta^2 / (pi/2 - theta)^2 beyond (Nguyen, Izadi, Lovell 2012); lateral noise
sigma_L = 0.8 + 0.035 theta / (pi/2 - theta) px; disparity quantisation 1/z = -2.85e-3 d + 3.0
with integer d (Khoshelham, Oude Elberink 2012); no return at depth edges, at grazing angles and
in the shadow of the IR projector, 7.5 cm beside the IR camera.

Lateral noise is simulated as a real Kinect shows it: the depth stored at pixel (u, v) is the depth
of a slightly displaced ray, and the point is rebuilt from (u, v) and that depth as a driver does
(x = (u - cx) z / fx). The cloud is organized, in `camera_depth_optical_frame` (z forward, x right,
y down), NaN where there is no return.

This module deliberately shares no code with the inspection (`vi_node`): the simulator is the
reference the inspection is tested against, so a wrong frame convention in one shows up as a test
failure instead of cancelling out.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile, rotation_from_rpy
from tiling_assembly.open3d_loader import import_open3d
from tiling_assembly.structure import Structure

Array = NDArray[np.float64]

FLOOR_LABEL = 0  # label image values: tile id (> 0) for structure tiles, these for the rest
CLUTTER_LABEL = -1
NO_RETURN_LABEL = -2

# camera_link (x forward, y left, z up) -> camera_depth_optical_frame (z forward, x right, y down)
OPTICAL_FROM_LINK = rotation_from_rpy(-math.pi / 2, 0.0, -math.pi / 2)


@dataclass(frozen=True)
class PinholeIntrinsics:
    """Pinhole model of the depth camera, in pixels, for a `width` x `height` image."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def scaled(self, width: int, height: int) -> PinholeIntrinsics:
        """The same camera at another resolution (e.g. the Kinect's 320x240 mode)."""
        sx, sy = width / self.width, height / self.height
        return PinholeIntrinsics(
            self.fx * sx, self.fy * sy, (self.cx + 0.5) * sx - 0.5, (self.cy + 0.5) * sy - 0.5, width, height
        )


KINECT_V1_DEPTH = PinholeIntrinsics(fx=580.0, fy=580.0, cx=319.5, cy=239.5, width=640, height=480)


@dataclass(frozen=True)
class KinectNoise:
    """Which parts of the Kinect v1 error model to apply, and their constants."""

    axial: bool = True
    lateral: bool = True
    quantisation: bool = True
    shadow: bool = True
    baseline: float = 0.075  # m, the IR projector sits at +x of the IR camera (optical frame)
    edge_dropout: float = 0.5  # probability of no return on a pixel at a depth edge
    grazing_start: float = math.radians(78.0)  # incidence where returns start to drop out ...
    grazing_end: float = math.radians(88.0)  # ... and where none are left
    speckle_dropout: float = 0.001  # probability of a random missing pixel
    min_range: float = 0.5  # m
    max_range: float = 4.5  # m
    depth_resolution: float = 0.001  # m, drivers publish depth in millimetres

    @classmethod
    def ideal(cls) -> KinectNoise:
        """Exact depths (range limits kept): for tests of geometry and frames."""
        return cls(
            axial=False,
            lateral=False,
            quantisation=False,
            shadow=False,
            edge_dropout=0.0,
            grazing_start=math.pi,
            grazing_end=math.pi,
            speckle_dropout=0.0,
            depth_resolution=0.0,
        )

    def axial_sigma(self, z: Array, incidence: Array) -> Array:
        """Standard deviation of the depth (m) at depth z (m) and incidence angle (rad)."""
        sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
        steep = np.clip(incidence, 0.0, math.radians(89.0))
        extra = 0.0001 / np.sqrt(np.maximum(z, 1e-3)) * steep**2 / (math.pi / 2 - steep) ** 2
        return np.where(incidence > math.radians(60.0), sigma + extra, sigma)

    @staticmethod
    def lateral_sigma(incidence: Array) -> Array:
        """Standard deviation of the pixel position (px) at an incidence angle (rad)."""
        steep = np.clip(incidence, 0.0, math.radians(85.0))
        return 0.8 + 0.035 * steep / (math.pi / 2 - steep)


@dataclass(frozen=True)
class ClutterBox:
    """A box standing on the floor or in the air: another robot, a bin, a person's foot."""

    center: tuple[float, float, float]  # m, map frame
    size: tuple[float, float, float]  # m, along the box's own x, y, z
    yaw: float = 0.0  # rad

    def mesh(self) -> tuple[Array, NDArray[np.int64]]:
        """Vertices (8, 3) and outward-wound triangles (12, 3)."""
        sx, sy, sz = (s / 2 for s in self.size)
        corners = np.array([[x, y, z] for z in (-sz, sz) for y in (-sy, sy) for x in (-sx, sx)], dtype=float)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        tris = np.array(
            [
                [0, 2, 1],
                [1, 2, 3],
                [4, 5, 6],
                [5, 7, 6],
                [0, 1, 4],
                [1, 5, 4],
                [2, 6, 3],
                [3, 6, 7],
                [0, 4, 2],
                [2, 4, 6],
                [1, 3, 5],
                [3, 7, 5],
            ],
            dtype=np.int64,
        )
        return corners @ rot.T + np.asarray(self.center, dtype=float), tris


def camera_pose(
    base_x: float,
    base_y: float,
    base_yaw: float,
    mount_xyz: tuple[float, float, float],
    mount_rpy: tuple[float, float, float],
    base_z: float = 0.0,
    base_roll: float = 0.0,
    base_pitch: float = 0.0,
) -> Array:
    """4x4 pose of `camera_depth_optical_frame` in `map` for a robot base pose and camera mount.

    base_z/roll/pitch model a base that does not sit perfectly flat (floor unevenness, suspension).
    """
    base = np.eye(4)
    base[:3, :3] = rotation_from_rpy(base_roll, base_pitch, base_yaw)
    base[:3, 3] = (base_x, base_y, base_z)
    mount = np.eye(4)
    mount[:3, :3] = rotation_from_rpy(*mount_rpy)
    mount[:3, 3] = mount_xyz
    optical = np.eye(4)
    optical[:3, :3] = OPTICAL_FROM_LINK
    return base @ mount @ optical


class KinectScene:
    """What is physically in front of the Kinect, as an Open3D ray casting scene.

    Built once from the physically present tiles (S_p), the floor and optional clutter, and reused
    for every scan while nothing changes.
    """

    def __init__(
        self,
        tiles: Iterable[PlacedTile] = (),
        clutter: Iterable[ClutterBox | PlacedTile] = (),
        floor: bool = True,
        floor_half_size: float = 30.0,
    ) -> None:
        o3d = import_open3d()
        self._o3d = o3d
        self.scene = o3d.t.geometry.RaycastingScene()
        labels: list[int] = []
        self.tile_ids: list[int] = []
        for tile in tiles:
            tris, _ = tile.triangles
            self._add(tile.vertices, tris)
            labels.append(int(tile.tile_id))
            self.tile_ids.append(int(tile.tile_id))
        for item in clutter:
            if isinstance(item, ClutterBox):
                vertices, tris = item.mesh()
            else:
                vertices, (tris, _) = item.vertices, item.triangles
            self._add(vertices, tris)
            labels.append(CLUTTER_LABEL)
        if floor:
            h = floor_half_size
            self._add(
                np.array([[-h, -h, 0.0], [h, -h, 0.0], [h, h, 0.0], [-h, h, 0.0]]),
                np.array([[0, 1, 2], [0, 2, 3]]),
            )
            labels.append(FLOOR_LABEL)
        # geometry id -> label; the last entry answers Open3D's INVALID_ID (no hit)
        self._labels = np.array([*labels, NO_RETURN_LABEL], dtype=np.int64)

    @classmethod
    def from_structure(
        cls,
        structure: Structure,
        present: Iterable[int] | None = None,
        clutter: Iterable[ClutterBox | PlacedTile] = (),
        floor: bool = True,
    ) -> KinectScene:
        """The tiles of `structure` that are physically there (all when `present` is None)."""
        ids = structure.tile_ids if present is None else sorted(set(present) & set(structure.tiles))
        return cls((structure.tiles[i] for i in ids), clutter, floor)

    def _add(self, vertices: Array, triangles: NDArray[np.int64]) -> None:
        core = self._o3d.core
        self.scene.add_triangles(
            core.Tensor(np.ascontiguousarray(vertices, dtype=np.float32)),
            core.Tensor(np.ascontiguousarray(triangles, dtype=np.uint32)),
        )

    def cast(self, origin: Array, directions: Array) -> tuple[Array, NDArray[np.int64], Array]:
        """First hits of rays from `origin` ((3,) or (..., 3)) along `directions` (..., 3).

        Returns the hit parameter t (hit = origin + t * direction, inf for none), the label of
        what was hit (tile id, FLOOR_LABEL, CLUTTER_LABEL or NO_RETURN_LABEL) and the surface
        normal in the map frame.
        """
        directions = np.asarray(directions)
        rays = np.empty((*directions.shape[:-1], 6), dtype=np.float32)
        rays[..., :3] = origin
        rays[..., 3:] = directions
        result = self.scene.cast_rays(self._o3d.core.Tensor.from_numpy(rays))
        t_hit = result["t_hit"].numpy().astype(np.float64)
        ids = np.minimum(result["geometry_ids"].numpy(), len(self._labels) - 1)
        return t_hit, self._labels[ids], result["primitive_normals"].numpy()


class KinectSimulator:
    """Simulated Kinect v1 depth camera producing organized point clouds.

    `scan(scene, pose)` returns an (H, W, 3) float32 cloud in the optical frame, NaN = no return;
    `pose` is the 4x4 pose of `camera_depth_optical_frame` in `map` (see `camera_pose`).
    """

    def __init__(
        self,
        intrinsics: PinholeIntrinsics = KINECT_V1_DEPTH,
        noise: KinectNoise | None = None,
        seed: int | None = None,
    ) -> None:
        self.intrinsics = intrinsics
        self.noise = noise if noise is not None else KinectNoise()
        self.rng = np.random.default_rng(seed)
        k = intrinsics
        v, u = np.mgrid[0 : k.height, 0 : k.width].astype(np.float64)
        self._u, self._v = u, v
        self._rays = np.stack([(u - k.cx) / k.fx, (v - k.cy) / k.fy, np.ones_like(u)], axis=-1)

    def with_noise(self, **changes: Any) -> KinectSimulator:
        """A simulator with some noise constants changed (same intrinsics, fresh random stream)."""
        return KinectSimulator(self.intrinsics, replace(self.noise, **changes), int(self.rng.integers(2**31)))

    def pixels_showing(self, scene: KinectScene, pose: Array, label: int) -> int:
        """Pixels of a frame from `pose` on which `label` (a tile id) is the first thing hit, within
        range and short of the incidence where returns give out: what a scan could show of it at
        best (no noise, no projector shadow, no random draws: the scans' random stream is untouched)."""
        directions = self._rays @ np.asarray(pose)[:3, :3].T
        depth, labels, normals = scene.cast(np.asarray(pose)[:3, 3], directions)
        shown = (labels == label) & (depth >= self.noise.min_range) & (depth <= self.noise.max_range)
        return int(np.count_nonzero(shown & (self._incidence(directions, normals) < self.noise.grazing_end)))

    def scan(self, scene: KinectScene, pose: Array) -> NDArray[np.float32]:
        """One depth frame of `scene` from `pose`: (H, W, 3) float32, NaN where there is no return."""
        return self.scan_labelled(scene, pose)[0]

    def scan_labelled(self, scene: KinectScene, pose: Array) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        """The cloud and, per pixel, what it shows (tile id, FLOOR/CLUTTER/NO_RETURN_LABEL)."""
        noise, rng, k = self.noise, self.rng, self.intrinsics
        rotation, origin = np.asarray(pose)[:3, :3], np.asarray(pose)[:3, 3]
        shape = (k.height, k.width)

        t_ideal, labels, normals = scene.cast(origin, self._rays @ rotation.T)
        incidence = self._incidence(self._rays @ rotation.T, normals)
        if noise.lateral:
            spread = noise.lateral_sigma(np.where(np.isfinite(t_ideal), incidence, 0.0))
            du = rng.normal(size=shape) * spread
            dv = rng.normal(size=shape) * spread
            rays = np.stack(
                [(self._u + du - k.cx) / k.fx, (self._v + dv - k.cy) / k.fy, np.ones(shape)], axis=-1
            )
            directions = rays @ rotation.T
            depth, labels, normals = scene.cast(origin, directions)
            incidence = self._incidence(directions, normals)
        else:
            directions = self._rays @ rotation.T
            depth = t_ideal  # the rays' z is 1 in the optical frame: t is the optical depth

        valid = np.isfinite(depth) & (depth >= noise.min_range) & (depth <= noise.max_range)
        if noise.shadow:
            valid &= ~self._in_projector_shadow(scene, origin, rotation, directions, depth, valid)
        if noise.edge_dropout > 0:
            edges = self._depth_edges(np.where(np.isfinite(t_ideal), t_ideal, 1e3))
            valid &= ~(edges & (rng.random(shape) < noise.edge_dropout))
        if noise.grazing_end < math.pi:
            drop = np.clip(
                (incidence - noise.grazing_start) / (noise.grazing_end - noise.grazing_start), 0, 1
            )
            valid &= rng.random(shape) >= drop
        if noise.speckle_dropout > 0:
            valid &= rng.random(shape) >= noise.speckle_dropout

        z = np.where(valid, depth, 1.0)
        if noise.axial:
            z = z + rng.normal(size=shape) * noise.axial_sigma(z, incidence)
        if noise.quantisation:
            disparity = np.round((3.0 - 1.0 / np.maximum(z, 0.1)) / 2.85e-3)
            z = 1.0 / (3.0 - 2.85e-3 * disparity)
        if noise.depth_resolution > 0:
            z = np.round(z / noise.depth_resolution) * noise.depth_resolution
        z = np.where(valid, z, np.nan)
        cloud = np.empty((*shape, 3), dtype=np.float32)
        cloud[..., 0] = (self._u - k.cx) * z / k.fx
        cloud[..., 1] = (self._v - k.cy) * z / k.fy
        cloud[..., 2] = z
        return cloud, np.where(valid, labels, NO_RETURN_LABEL)

    @staticmethod
    def _incidence(directions: Array, normals: Array) -> Array:
        """Angle between each ray and the surface normal it hit (rad); 0 where nothing was hit."""
        # Open3D's normals are unit (zero where nothing was hit)
        norm = np.sqrt(np.einsum("...i,...i->...", directions, directions))
        cosine = np.abs(np.einsum("...i,...i->...", directions, normals)) / norm
        return np.arccos(np.clip(cosine, 0.0, 1.0))

    def _in_projector_shadow(
        self,
        scene: KinectScene,
        origin: Array,
        rotation: Array,
        directions: Array,
        depth: Array,
        valid: NDArray[np.bool_],
    ) -> NDArray[np.bool_]:
        """Pixels whose surface point the IR projector cannot light (something is in between)."""
        projector = origin + rotation @ np.array([self.noise.baseline, 0.0, 0.0])
        points = origin + directions[valid] * depth[valid, None]
        to_point = points - projector
        t_hit, _, _ = scene.cast(projector, to_point)
        length = np.sqrt(np.einsum("ij,ij->i", to_point, to_point))
        shadowed = np.zeros(valid.shape, dtype=bool)
        shadowed[valid] = t_hit < 1.0 - 0.005 / np.maximum(length, 1e-6)
        return shadowed

    @staticmethod
    def _depth_edges(depth: Array) -> NDArray[np.bool_]:
        """Pixels next to a depth jump well above the sensor noise (the Kinect loses them)."""
        jump = 0.025 + 0.01 * np.minimum(depth, 10.0) ** 2
        edges = np.zeros(depth.shape, dtype=bool)
        dx = np.abs(np.diff(depth, axis=1)) > np.minimum(jump[:, 1:], jump[:, :-1])
        dy = np.abs(np.diff(depth, axis=0)) > np.minimum(jump[1:, :], jump[:-1, :])
        edges[:, 1:] |= dx
        edges[:, :-1] |= dx
        edges[1:, :] |= dy
        edges[:-1, :] |= dy
        return edges
