"""One depth scan end to end: align it to S_a, ray-trace S_a, classify every tile (section 2.2).

Stages, each its own module: `pose_prior` (overhead pose + mount), `floor` (height, roll, pitch),
`candidates` (C_1), `coarse_alignment` (x, y, yaw search), `icp` (against `patches` or the Open3D
BVH of `raycast`), `raycast` (the virtual scan C_v), then `classify` (paper rules). Every stage is
timed. A scan that cannot be aligned gives no tile states at all, never wrong ones.

The expected structure's models (patches, ray casting scene, coarse search grid) are built once per
S_a and reused while it is unchanged.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import rpy_from_rotation
from tiling_assembly.structure import Structure
from vi_node.camera_model import OPTICAL_FROM_LINK, PinholeCamera
from vi_node.candidates import Candidates, select_candidates
from vi_node.classify import TileState, classify_paper
from vi_node.coarse_alignment import CoarseAligner, CoarseSettings
from vi_node.floor import FloorSettings, correct_pose, fit_floor
from vi_node.icp import Correspondences, IcpSettings, point_to_plane_icp
from vi_node.inspection_settings import InspectionSettings
from vi_node.patches import PlanarPatches
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior
from vi_node.raycast import VirtualScan, VirtualScene

Array = NDArray[np.float64]


@dataclass
class TileResult:
    """What one scan says about one expected tile."""

    tile_id: int
    state: TileState
    physical: int  # p_i
    virtual: int  # v_i
    ratio: float  # min(p/v, v/p)
    residual: float = 0.0  # m, RMS distance of the physical support to the tile's faces


@dataclass
class ScanResult:
    """The outcome of one scan: tile results, or the reason there are none."""

    ok: bool
    reason: str = ""
    tiles: list[TileResult] = field(default_factory=list)
    camera_pose: Array | None = None  # 4x4 aligned pose of the optical frame in the map (P_v)
    alignment_rms: float = math.nan
    candidates: int = 0
    timings: dict[str, float] = field(default_factory=dict)  # stage -> seconds
    notes: list[str] = field(default_factory=list)  # warnings that did not stop the scan

    def by_id(self) -> dict[int, TileResult]:
        return {t.tile_id: t for t in self.tiles}


class ExpectedModel:
    """Everything derived from one S_a, built once and reused for every scan of it."""

    def __init__(self, structure: Structure, tile_ids: Iterable[int], settings: InspectionSettings) -> None:
        self.tile_ids = tuple(sorted(set(tile_ids) & set(structure.tiles)))
        tiles = [structure.tiles[i] for i in self.tile_ids]
        self.tiles = tiles
        self.patches = PlanarPatches(tiles)
        self.scene = VirtualScene(tiles)
        self.low, self.high = self.patches.low, self.patches.high
        self.coarse = (
            CoarseAligner(
                self.scene,
                self.low,
                self.high,
                settings.floor_clearance,
                CoarseSettings(yaw_range=settings.coarse_yaw_range, shift_range=settings.coarse_shift_range),
            )
            if tiles
            else None
        )

    def __len__(self) -> int:
        return len(self.tile_ids)


class _Timer:
    def __init__(self) -> None:
        self.timings: dict[str, float] = {}
        self._last = time.perf_counter()

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.timings[stage] = self.timings.get(stage, 0.0) + now - self._last
        self._last = now


class InspectionPipeline:
    """The visual inspection of one structure; `inspect` runs one scan."""

    def __init__(
        self, structure: Structure, expected: Iterable[int] | None, settings: InspectionSettings
    ) -> None:
        settings.validate()
        self.structure = structure
        self.settings = settings
        fx, fy, cx, cy = settings.intrinsics
        width, height = settings.intrinsics_size
        self.camera = PinholeCamera(fx, fy, cx, cy, int(width), int(height))
        self.mount = CameraMount(tuple(settings.camera_xyz), tuple(settings.camera_rpy))  # type: ignore[arg-type]
        self._models: dict[tuple[int, ...], ExpectedModel] = {}
        self.model = self._model_for(structure.tile_ids if expected is None else expected)

    @property
    def expected_ids(self) -> tuple[int, ...]:
        return self.model.tile_ids

    def set_expected(self, expected: Iterable[int]) -> None:
        """Change S_a (models are cached per S_a, so going back and forth is cheap)."""
        self.model = self._model_for(expected)

    def _model_for(self, expected: Iterable[int]) -> ExpectedModel:
        key = tuple(sorted(set(expected) & set(self.structure.tiles)))
        if key not in self._models:
            if len(self._models) >= 8:
                self._models.pop(next(iter(self._models)))
            self._models[key] = ExpectedModel(self.structure, key, self.settings)
        return self._models[key]

    # ----------------------------------------------------------------------------------------------
    def inspect(self, cloud: NDArray[np.float32], overhead: OverheadPose) -> ScanResult:
        """Classify every tile of S_a from one organized cloud and the overhead pose of its time."""
        timer = _Timer()
        s = self.settings
        model = self.model
        problem = self._check_cloud(cloud)
        if problem:
            return ScanResult(False, problem, timings=timer.timings)
        try:
            camera = self.camera.at_resolution(cloud.shape[1], cloud.shape[0])
        except ValueError as error:
            return ScanResult(False, str(error), timings=timer.timings)
        if len(model) == 0:
            return ScanResult(
                True, "", [], None, timings=timer.timings, notes=["S_a is empty: nothing to inspect"]
            )
        notes: list[str] = []
        timer.lap("check")

        prior = camera_prior(overhead, self.mount)
        timer.lap("prior")
        floor = fit_floor(cloud, prior, model.low, model.high, FloorSettings(stride=s.floor_stride))
        if floor is None:
            notes.append(
                "floor not found near where the mount predicts it: using the mount's height, roll, pitch"
            )
            pose = prior
        else:
            pose = correct_pose(prior, floor)
        timer.lap("floor")

        if s.coarse_search and model.coarse is not None:
            reach = float(np.linalg.norm(0.5 * (model.low + model.high) - pose[:3, 3]))
            wide = s.box_margin + s.coarse_shift_range + s.coarse_yaw_range * (reach + 0.3)
            wide_candidates = select_candidates(
                cloud, camera, pose, model.low, model.high, wide, s.floor_clearance
            )
            timer.lap("candidates")
            if len(wide_candidates) < s.min_alignment_points:
                return self._failed(
                    f"alignment failed: only {len(wide_candidates)} points near the expected structure",
                    timer,
                    notes,
                )
            coarse = model.coarse.align(wide_candidates.points, pose[:3, 3])
            if (
                coarse is None
                or coarse.on_surface < 0.25
                or coarse.on_surface_points < s.min_alignment_points
            ):
                share = 0.0 if coarse is None else coarse.on_surface
                return self._failed(
                    f"alignment failed: no x/y/yaw puts the scan on S_a ({share:.0%} of points on it)",
                    timer,
                    notes,
                )
            pose = coarse.correction @ pose
            timer.lap("coarse")

        candidates = select_candidates(
            cloud, camera, pose, model.low, model.high, s.box_margin, s.floor_clearance
        )
        timer.lap("candidates")
        if len(candidates) < s.min_alignment_points:
            return self._failed(f"alignment failed: only {len(candidates)} candidate points", timer, notes)

        structure_correspond = self._correspondence_function(model, pose[:3, 3].copy())
        structure_points = candidates.points
        floor_points = np.zeros((0, 3)) if floor is None else floor.sample @ pose[:3, :3].T + pose[:3, 3]
        count = len(structure_points)

        def correspond(points: Array, cut: float) -> Correspondences:
            on_structure = structure_correspond(points[:count], cut)
            on_floor = points[count:]
            return Correspondences(
                np.vstack([on_structure.closest, on_floor * np.array([1.0, 1.0, 0.0])]),
                np.vstack([on_structure.normal, np.tile([0.0, 0.0, 1.0], (len(on_floor), 1))]),
                np.concatenate([on_structure.distance, np.abs(on_floor[:, 2])]),
            )

        icp = point_to_plane_icp(
            np.vstack([structure_points, floor_points]),
            correspond,
            IcpSettings(max_iterations=s.icp_max_iterations),
        )
        pose = icp.correction @ pose
        aligned = Candidates(
            candidates.points @ icp.correction[:3, :3].T + icp.correction[:3, 3],
            candidates.optical,
            candidates.pixels,
        )
        final = structure_correspond(
            structure_points @ icp.correction[:3, :3].T + icp.correction[:3, 3], 0.01
        )
        on_structure = int(np.count_nonzero(final.distance <= 0.01))
        timer.lap("icp")

        failure = self._check_alignment(prior, pose, on_structure, count)
        if failure:
            return self._failed(failure, timer, notes)

        rows, cols = camera.box_roi(pose, model.low, model.high)
        virtual = model.scene.cast(camera, pose, rows, cols, s.min_range, s.max_range)
        timer.lap("raycast")

        tiles = self._classify_paper(model, aligned, virtual, pose)
        timer.lap("classify")
        return ScanResult(True, "", tiles, pose, icp.rms, len(candidates), timer.timings, notes)

    def _correspondence_function(
        self, model: ExpectedModel, camera_position: Array
    ) -> Callable[[Array, float], Correspondences]:
        """Projections onto S_a through the paper's patch hierarchy (faces turned away left out)."""

        def by_patches(points: Array, cut: float) -> Correspondences:
            projection = model.patches.project(points, cut, camera_position)
            return Correspondences(projection.closest, projection.normal, projection.distance)

        return by_patches

    # ----------------------------------------------------------------------------------------------
    def _classify_paper(
        self, model: ExpectedModel, aligned: Candidates, virtual: VirtualScan, pose: Array
    ) -> list[TileResult]:
        """p_i from the candidates' projections onto S_a, v_i from the virtual scan; section 2.2.3."""
        s = self.settings
        projection = model.patches.project(aligned.points, s.support_distance, pose[:3, 3])
        found = projection.found
        physical = np.bincount(projection.tile[found], minlength=len(model)).astype(np.int64)
        squared = np.bincount(
            projection.tile[found], weights=projection.distance[found] ** 2, minlength=len(model)
        )
        residual = np.sqrt(squared / np.maximum(physical, 1))
        # the candidates lost everything lower than floor_clearance: so must the virtual points,
        # or every tile standing on the floor would look half missing
        visible = virtual.tile >= 0
        rays = self.camera.at_resolution(*virtual.size).rays[virtual.rows, virtual.cols][visible]
        height = (rays * virtual.depth[visible][:, None]) @ pose[2, :3] + pose[2, 3]
        kept = virtual.tile[visible][height >= s.floor_clearance]
        virtual_support = np.bincount(kept, minlength=len(model)).astype(np.int64)
        states, ratio = classify_paper(physical, virtual_support, s.min_support, s.ratio_threshold)
        return [
            TileResult(
                int(tile_id),
                TileState(int(states[k])),
                int(physical[k]),
                int(virtual_support[k]),
                float(ratio[k]),
                float(residual[k]),
            )
            for k, tile_id in enumerate(model.tile_ids)
        ]

    def _check_cloud(self, cloud: object) -> str:
        if not isinstance(cloud, np.ndarray) or cloud.ndim != 3 or cloud.shape[2] != 3:
            shape = getattr(cloud, "shape", None)
            return f"bad cloud: expected an organized (H, W, 3) array, got shape {shape}"
        if cloud.shape[0] < 2 or cloud.shape[1] < 2:
            return f"bad cloud: {cloud.shape[1]}x{cloud.shape[0]} is not an organized image"
        valid = np.count_nonzero(np.isfinite(cloud[::4, ::4, 2]))
        if valid == 0:
            return "bad cloud: no valid points (all NaN or empty)"
        return ""

    def _check_alignment(self, prior: Array, pose: Array, inliers: int, points: int) -> str:
        s = self.settings
        if inliers < s.min_alignment_points or inliers < s.min_alignment_inliers * points:
            return f"alignment failed: ICP kept only {inliers} of {points} points on S_a"
        shift = float(np.linalg.norm(pose[:2, 3] - prior[:2, 3]))
        turn = abs(_yaw(pose) - _yaw(prior))
        turn = min(turn, 2 * math.pi - turn)
        if shift > s.max_pose_correction or turn > s.max_yaw_correction:
            return (
                f"alignment failed: the correction of the overhead pose ({shift * 100:.0f} cm, "
                f"{math.degrees(turn):.0f} deg) is beyond belief"
            )
        return ""

    @staticmethod
    def _failed(reason: str, timer: _Timer, notes: list[str]) -> ScanResult:
        return ScanResult(False, reason, timings=timer.timings, notes=notes)


def _yaw(pose: Array) -> float:
    return rpy_from_rotation(pose[:3, :3] @ OPTICAL_FROM_LINK.T)[2]
