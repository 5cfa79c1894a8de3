"""One depth scan end to end: align it to S_a, ray-trace S_a, classify every tile (section 2.2).

Stages, each its own module: `pose_prior` (overhead pose + mount), `floor` (height, roll, pitch),
`candidates` (C_1), `coarse_alignment` (x, y, yaw search), `icp` (point-to-plane, with the floor
as part of the known scene), `raycast` (the virtual scan C_v), then the classification:

- `paper` mode: projections of the candidates through the `patches` hierarchy give p_i, the
  virtual scan v_i, and `classify` applies the paper's rules (section 2.2.3);
- `default` mode: `evidence` compares measured and virtual depth pixel by pixel (agree,
  see-through, in front, no return), decides every tile relative to what the virtual scan predicts
  for it, and `misplacement` refits tiles whose points sit off their faces. ICP runs on a
  subsample of the candidates against Open3D's BVH instead of the patch hierarchy.

Every stage is timed. A scan that cannot be aligned gives no tile states at all, never wrong ones.
The models of an S_a (patches, ray casting scene, coarse search grid) are built once and reused.
Fusion across scans (`fusion`) is left to the caller, which knows which scans belong together.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Sequence

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import rpy_from_rotation
from tiling_assembly.structure import Structure
from vi_node.camera_model import OPTICAL_FROM_LINK, PinholeCamera
from vi_node.candidates import Candidates, select_candidates
from vi_node.classify import TileState, classify_paper
from vi_node.coarse_alignment import CoarseAligner, CoarseSettings
from vi_node.evidence import EvidenceSettings, TileEvidence, decide, pixel_evidence
from vi_node.floor import FloorFit, FloorSettings, correct_pose, fit_floor
from vi_node.icp import Correspondences, IcpSettings, point_to_plane_icp
from vi_node.inspection_settings import InspectionSettings
from vi_node.misplacement import MisplacementSettings, assess
from vi_node.patches import PlanarPatches
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior
from vi_node.raycast import VirtualScan, VirtualScene
from vi_node.scan_result import ScanResult, TileResult

Array = NDArray[np.float64]


class ExpectedModel:
    """Everything derived from one S_a, built once and reused for every scan of it."""

    def __init__(self, structure: Structure, tile_ids: Iterable[int], settings: InspectionSettings) -> None:
        self.tile_ids = tuple(sorted(set(tile_ids) & set(structure.tiles)))
        tiles = [structure.tiles[i] for i in self.tile_ids]
        self.tiles = tiles
        self.patches = PlanarPatches(tiles)
        self.scene = VirtualScene(tiles)
        self.low, self.high = self.patches.low, self.patches.high
        coarse = CoarseSettings(yaw_range=settings.coarse_yaw_range, shift_range=settings.coarse_shift_range)
        self.coarse = (
            CoarseAligner(self.scene, self.low, self.high, settings.floor_clearance, coarse)
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
        self.evidence_settings = EvidenceSettings(
            depth_sigmas=settings.depth_sigmas,
            depth_margin=settings.depth_margin,
            max_incidence=settings.max_incidence,
            min_observed_pixels=settings.min_observed_pixels,
            min_observed_fraction=settings.min_observed_fraction,
            present_fraction=settings.present_fraction,
            missing_fraction=settings.missing_fraction,
        )
        self.misplacement_settings = MisplacementSettings(
            shift=settings.misplacement_shift, turn=settings.misplacement_yaw
        )
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
        paper = s.mode == "paper"
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
        mismatch = camera.check_cloud(cloud)  # the driver's x = (u - cx) z / fx must hold
        if mismatch:
            notes.append(mismatch + ": check the intrinsics parameters")
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
            # the 1 cm voxels of the search need no more than every other pixel (default mode)
            stride = 1 if paper else 2
            near = select_candidates(
                cloud, camera, pose, model.low, model.high, wide, s.floor_clearance, stride
            )
            timer.lap("candidates")
            if len(near) < s.min_alignment_points // stride**2:
                return self._failed(
                    f"alignment failed: only {len(near)} points near the expected structure", timer, notes
                )
            coarse = model.coarse.align(near.points, pose[:3, 3])
            if (
                coarse is None
                or coarse.on_surface < 0.25
                or coarse.on_surface_points < s.min_alignment_points // stride**2
            ):
                share = 0.0 if coarse is None else coarse.on_surface
                reason = f"alignment failed: no x/y/yaw puts the scan on S_a ({share:.0%} of points on it)"
                return self._failed(reason, timer, notes)
            pose = coarse.correction @ pose
            timer.lap("coarse")

        candidates = select_candidates(
            cloud, camera, pose, model.low, model.high, s.box_margin, s.floor_clearance
        )
        timer.lap("candidates")
        if len(candidates) < s.min_alignment_points:
            return self._failed(f"alignment failed: only {len(candidates)} candidate points", timer, notes)

        result = self._align_and_classify(cloud, camera, model, prior, pose, floor, candidates, timer, notes)
        if paper or not result.ok or not any(flagged for flagged, _, _ in result.misplacement.values()):
            return result
        # a misplaced tile pulls the alignment towards where it lies: align once more, from the
        # coarse fit, without the points around the tiles found misplaced, and judge everything again
        assert result.camera_pose is not None
        keep = np.ones(len(candidates), dtype=bool)
        correction = result.camera_pose @ np.linalg.inv(pose)  # the first ICP's
        placed = Candidates(
            candidates.points @ correction[:3, :3].T + correction[:3, 3],
            candidates.optical,
            candidates.pixels,
        )
        moved_points = placed.points
        for tile_id, (flagged, offset, _) in result.misplacement.items():
            if flagged:
                index = model.tile_ids.index(tile_id)
                reach = self.misplacement_settings.reach + math.hypot(offset[0], offset[1])
                low, high = model.patches.tile_low[index] - reach, model.patches.tile_high[index] + reach
                keep &= ~np.all((moved_points >= low) & (moved_points <= high), axis=1)
        if keep.sum() < s.min_alignment_points:
            return self._unless_all_moved(result, timer, notes)
        second = self._align_and_classify(
            cloud,
            camera,
            model,
            prior,
            pose,  # from the coarse fit again: the first ICP may have been dragged off
            floor,
            candidates.subset(keep),
            timer,
            notes,
            rejudge=candidates,
            suspects=[
                model.tile_ids.index(t) for t, (flagged, _, _) in result.misplacement.items() if flagged
            ],
        )
        return self._unless_all_moved(second if second.ok else result, timer, notes)

    def _unless_all_moved(self, result: ScanResult, timer: _Timer, notes: list[str]) -> ScanResult:
        """No states from a scan in which many tiles seem moved: a misalignment, far more likely than
        several tiles misplaced at once (or the whole structure was pushed: S_a no longer fits)."""
        judged = len(result.misplacement)
        moved = sum(flagged for flagged, _, _ in result.misplacement.values())
        if moved >= 2 and moved >= 0.25 * judged:
            return self._failed(
                f"alignment doubtful: {moved} of {judged} tiles seem moved together", timer, notes
            )
        return result

    def _align_and_classify(
        self,
        cloud: NDArray[np.float32],
        camera: PinholeCamera,
        model: ExpectedModel,
        prior: Array,
        pose: Array,
        floor: FloorFit | None,
        candidates: Candidates,
        timer: _Timer,
        notes: list[str],
        rejudge: Candidates | None = None,
        suspects: Sequence[int] = (),
    ) -> ScanResult:
        """ICP of `candidates` (and the floor) from `pose`, the checks, the virtual scan and the
        classification. `rejudge`: the candidates to judge placement on, when ICP used fewer;
        `suspects`: tiles (indices) found misplaced before, refitted whatever the first step says."""
        s = self.settings
        paper = s.mode == "paper"
        structure_correspond = self._correspondence_function(model, pose[:3, 3].copy())
        if paper:
            structure_points = candidates.points
        else:
            structure_points = candidates.points[:: max(1, math.ceil(len(candidates) / s.icp_max_points))]
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
        judged = rejudge if rejudge is not None else candidates
        correction = icp.correction
        aligned = Candidates(
            judged.points @ correction[:3, :3].T + correction[:3, 3], judged.optical, judged.pixels
        )
        timer.lap("icp")

        if paper:
            final = structure_correspond(
                structure_points @ icp.correction[:3, :3].T + icp.correction[:3, 3], 0.01
            )
            on_structure, nearest_tile = final.distance, None
            closest = normals = np.zeros((0, 3))
        else:  # one closest-point query serves the check and the misplacement
            aligned = aligned.subset(
                slice(None, None, max(1, math.ceil(len(aligned) / s.misplacement_points)))
            )
            closest, normals, nearest_tile = model.scene.closest_points(aligned.points)
            on_structure = np.sqrt(np.einsum("ij,ij->i", aligned.points - closest, aligned.points - closest))
            if rejudge is not None:  # the check concerns the points ICP used
                inside = np.isin(aligned.pixels, candidates.pixels)
                on_structure = on_structure[inside]
        failure = self._check_alignment(
            prior, pose, int(np.count_nonzero(on_structure <= 0.01)), len(on_structure)
        )
        if failure:
            return self._failed(failure, timer, notes)
        timer.lap("check alignment")

        rows, cols = camera.box_roi(pose, model.low, model.high)
        virtual = model.scene.cast(camera, pose, rows, cols, s.min_range, s.max_range)
        timer.lap("raycast")

        # a scan that contradicts most of what S_a predicts is misaligned (a fragment of the structure
        # fitted to the wrong place), or S_a is mostly gone: either way no states from it
        evidence = pixel_evidence(cloud, virtual, len(model), self.evidence_settings)
        agree, observed = int(evidence.agree.sum()), int(evidence.observed.sum())
        if observed >= s.min_observed_pixels and agree < s.min_agreement * observed:
            reason = (
                f"alignment doubtful: the scan agrees with only {agree / observed:.0%} of what S_a predicts"
            )
            return self._failed(reason, timer, notes)
        timer.lap("evidence")

        result = ScanResult(
            True, "", [], pose, icp.rms, len(candidates), timer.timings, notes, model.tile_ids
        )
        if paper:
            self._classify_paper(model, aligned, virtual, pose, result)
            timer.lap("classify")
        else:
            self._classify_default(evidence, model, result)
            timer.lap("classify")
            assert nearest_tile is not None
            self._judge_placement(model, aligned, nearest_tile, closest, normals, pose, result, suspects)
            timer.lap("misplacement")
        return result

    def _correspondence_function(
        self, model: ExpectedModel, camera_position: Array
    ) -> Callable[[Array, float], Correspondences]:
        """Projections onto S_a: the paper's patch hierarchy (faces turned away left out) in paper
        mode; Open3D's BVH closest points in default mode (same answer, a fraction of the time)."""
        if self.settings.mode == "paper":

            def by_patches(points: Array, cut: float) -> Correspondences:
                projection = model.patches.project(points, cut, camera_position)
                return Correspondences(projection.closest, projection.normal, projection.distance)

            return by_patches

        def by_bvh(points: Array, cut: float) -> Correspondences:
            closest, normal, _ = model.scene.closest_points(points)
            return Correspondences(
                closest, normal, np.sqrt(np.einsum("ij,ij->i", points - closest, points - closest))
            )

        return by_bvh

    # ----------------------------------------------------------------------------------------------
    def _classify_paper(
        self, model: ExpectedModel, aligned: Candidates, virtual: VirtualScan, pose: Array, result: ScanResult
    ) -> None:
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
        evidence = TileEvidence.zeros(len(model))
        evidence.agree, evidence.virtual = physical, virtual_support
        result.evidence, result.evidence_states = evidence, states
        result.tiles = [
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

    def _classify_default(self, evidence: TileEvidence, model: ExpectedModel, result: ScanResult) -> None:
        """Decide every tile from its pixel evidence, relative to what the virtual scan predicts for it."""
        states = decide(evidence, self.evidence_settings)
        result.evidence, result.evidence_states = evidence, states
        observed = np.maximum(evidence.observed, 1)
        result.tiles = [
            TileResult(
                int(tile_id),
                TileState(int(states[k])),
                int(evidence.agree[k]),
                int(evidence.virtual[k]),
                float(evidence.agree[k] / observed[k]),
                0.0,
                int(evidence.see_through[k]),
                int(evidence.in_front[k]),
                int(evidence.no_return[k]),
                int(evidence.judged[k]),
            )
            for k, tile_id in enumerate(model.tile_ids)
        ]

    def _judge_placement(
        self,
        model: ExpectedModel,
        aligned: Candidates,
        nearest_tile: NDArray[np.int64],
        closest: Array,
        normals: Array,
        pose: Array,
        result: ScanResult,
        suspects: Sequence[int] = (),
    ) -> None:
        """Per-tile residuals, and MISPLACED for tiles whose points a planar motion explains better."""
        fits = assess(
            aligned.points,
            aligned.optical[:, 2],
            nearest_tile,
            closest,
            normals,
            model.patches,
            pose[:3, 3],
            self.misplacement_settings,
            model.tiles,
            [t.state != TileState.MISSING for t in result.tiles],
            suspects,
            [t.see_through + t.in_front >= 1 for t in result.tiles],
            model.scene,
        )
        for index, fit in fits.items():
            tile = result.tiles[index]
            tile.residual = fit.residual
            # the pixels must agree with the refit: a tile that moved has left some of its expected
            # surface (see-through) or stands in front of it; a shift of 1.5 cm or more shows on a
            # good share of its pixels, a turn of a small tile on a few corners
            disagree = tile.see_through + tile.in_front
            shifted = math.hypot(fit.offset[0], fit.offset[1]) >= 0.6 * self.misplacement_settings.shift
            needed = max(1.0, 0.05 * (tile.physical + disagree)) if shifted else 1.0
            misplaced = fit.misplaced and disagree >= needed
            if fit.judged:
                result.misplacement[tile.tile_id] = (misplaced, fit.offset, fit.residual)
            if misplaced:
                tile.state, tile.offset = TileState.MISPLACED, fit.offset

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
