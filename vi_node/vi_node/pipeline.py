"""One depth scan end to end: align it to S_a, ray-trace S_a, classify every tile (section 2.2).

`InspectionPipeline.inspect` reads as the row of stages, each its own module: `pose_prior`
(overhead pose + mount), `floor` (height, roll, pitch), `robot_mask` (other robots in view, left
out of everything that follows), `coarse_alignment` (x, y, yaw search, its hypotheses ranked by
`view_agreement`), `candidates` (C_1), `icp`
(point-to-plane, with the floor as part of the known scene), `raycast` (the virtual scan C_v),
then the classification of the mode chosen at start-up:

- `paper`: projections of the candidates through the `patches` hierarchy give p_i, the virtual
  scan v_i, and `classify` applies the paper's rules (section 2.2.3). Nothing beyond the paper:
  no robot mask, ICP on every candidate.
- `default`: `evidence` judges every pixel between "the tile is there" and "the tile is gone"
  (the virtual scan, what lies behind each tile, and where the camera would return at all:
  `expected_returns`), `misplacement` refits tiles whose points sit off their faces, and
  `type_hypotheses` weighs a tile whose pixels disagree against the other types of its height in
  its place; a tile found misplaced is judged once more after an alignment that leaves it out. ICP runs on a
  subsample of the candidates against Open3D's BVH instead of the patch hierarchy.

In default mode, fits from different hypotheses that explain the scan nearly as well ("rivals": a
repetitive structure, a view of a few faces) each climb the view agreement; one the depth image then
bears out clearly best is aligned from alone, otherwise only the tiles all rivals agree on are judged.

Every stage is timed. A scan that cannot be aligned gives no tile states at all, never wrong ones;
one that cannot show S_a (the other robots stand in front of it) says so.
The models of an S_a (patches, ray casting scene, coarse search grid) are built once and reused.
Fusion across scans (`fusion`) is left to the caller, which knows which scans belong together.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile, rpy_from_rotation
from tiling_assembly.structure import Structure
from vi_node.blank_evidence import blank_evidence
from vi_node.camera_model import OPTICAL_FROM_LINK, PinholeCamera
from vi_node.candidates import Candidates, at_structure_range, select_candidates
from vi_node.classify import TileState, paper_support
from vi_node.coarse_alignment import CoarseAligner, CoarseSettings
from vi_node.evidence import TileEvidence, decide, judgeable, pixel_evidence, smooth, too_deep, unexpected
from vi_node.expected_returns import expect_returns
from vi_node.floor import FloorFit, FloorSettings, correct_pose, fit_floor
from vi_node.icp import Correspondences, IcpResult, IcpSettings, point_to_plane_icp
from vi_node.inspection_settings import InspectionSettings
from vi_node.misplacement import (
    PlacementContext,
    ScanPoints,
    assess,
    confirmed_by_pixels,
    hinted_motion,
    moved_as_one,
    other_shape,
    something_else_there,
    too_little_seen,
)
from vi_node.patches import PlanarPatches
from vi_node.periodicity import periodic_shifts
from vi_node.pose_hypotheses import DepthImage, fitted_pose_explains, pixels_at_fitted_pose
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior, pose_error
from vi_node.raycast import VirtualScan, VirtualScene
from vi_node.rival_fits import agreed, distinct, untold
from vi_node.robot_mask import RobotBoxes, inside_robots, near_robot_points, tall_things
from vi_node.scan_result import ScanResult, TileResult
from vi_node.type_hypotheses import TypeVotes, look_alike_rivals, rival_tiles, tiles_box, type_votes
from vi_node.view_agreement import DepthView, climb, view_agreement

Array = NDArray[np.float64]
Mask = NDArray[np.bool_]
Motion = tuple[float, float, float]  # a tile's x, y (m) and turn (rad) off its planned pose

# a scan that fails to align is aligned once more without each of this many largest tiles in turn
# (a search and an ICP each, only on failure): a misplaced tile large enough to pull a fit off is
# among the largest
LEAVE_OUT_TRIES = 3


class ExpectedModel:
    """Everything derived from one S_a, built once and reused for every scan of it."""

    def __init__(self, structure: Structure, tile_ids: Iterable[int], settings: InspectionSettings) -> None:
        self.tile_ids = tuple(sorted(set(tile_ids) & set(structure.tiles)))
        tiles = [structure.tiles[i] for i in self.tile_ids]
        self.tiles = tiles
        self.patches = PlanarPatches(tiles)
        self.scene = VirtualScene(tiles)
        self.low, self.high = self.patches.low, self.patches.high
        self.shifts = periodic_shifts(tiles, within=settings.coarse_shift_range)
        coarse = CoarseSettings(yaw_range=settings.coarse_yaw_range, shift_range=settings.coarse_shift_range)
        self.coarse = (
            CoarseAligner(self.scene, self.low, self.high, settings.floor_clearance, coarse)
            if tiles
            else None
        )

    def __len__(self) -> int:
        return len(self.tile_ids)


class InspectionStoppedError(Exception):
    """The caller asked the inspection to stop (its node is shutting down); raised between stages."""


class _Timer:
    """Each stage's time; between two stages, the point where a stop request ends the inspection
    (a scan takes seconds on a loaded machine, a stage a fraction of that)."""

    def __init__(self, stop_requested: Callable[[], bool] | None = None) -> None:
        self.timings: dict[str, float] = {}
        self._last = time.perf_counter()
        self._stop_requested = stop_requested

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self.timings[stage] = self.timings.get(stage, 0.0) + now - self._last
        self._last = now
        if self._stop_requested is not None and self._stop_requested():
            raise InspectionStoppedError(f"stopped after the {stage} stage")


@dataclass
class _Scan:
    """One scan on its way through the stages."""

    cloud: NDArray[np.float32]
    camera: PinholeCamera
    prior: Array  # the optical frame's pose from the overhead pose and the mount
    timer: _Timer = field(default_factory=_Timer)
    notes: list[str] = field(default_factory=list)
    floor: FloorFit | None = None
    masked: Mask | None = None  # (H, W) pixels of other robots and tall things
    # (H, W) pixels inside a robot's box but on S_a's surfaces: the alignment may use them, but no
    # tile is judged on them (a robot's body can pass for the faces of a tile that is gone)
    unjudged: Mask | None = None
    # (H, W) pixels masked only for lying inside a robot's box off S_a's surfaces (a subset of `masked`)
    robot_pixels: Mask | None = None
    robots: RobotBoxes | None = None  # the other robots the overhead cameras see
    # (pose, tile index, rival type): the type votes there, asked both for a tile that disagrees and
    # for one shown in place
    type_votes: dict[tuple[bytes, int, str], TypeVotes] = field(default_factory=dict)
    # the last C_v judged (with what lies behind its tiles) and the pose it was cast from: the type
    # votes reuse its rays rather than cast them again per tile and rival
    virtual: tuple[bytes, VirtualScan] | None = None

    def failed(self, reason: str) -> ScanResult:
        return ScanResult(ok=False, reason=reason, timings=self.timer.timings, notes=self.notes)

    def keep(self, candidates: Candidates) -> Candidates:
        """The candidates that are not masked."""
        if self.masked is None:
            return candidates
        return candidates.subset(~self.masked.reshape(-1)[candidates.pixels])


@dataclass(frozen=True)
class _Away:
    """Boxes (map frame under the camera pose `camera`) whose points an alignment leaves out."""

    camera: Array
    boxes: list[tuple[Array, Array]]

    def outside(self, points: Array, pose: Array) -> Mask:
        """Which `points` (map frame under the camera pose `pose`) lie outside every box."""
        move = self.camera @ np.linalg.inv(pose)
        placed = points @ move[:3, :3].T + move[:3, 3]
        keep = np.ones(len(points), dtype=bool)
        for low, high in self.boxes:
            keep &= ~np.all((placed >= low) & (placed <= high), axis=1)
        return keep


class InspectionPipeline:
    """The visual inspection of one structure; `inspect` runs one scan."""

    def __init__(
        self, structure: Structure, expected: Iterable[int] | None, settings: InspectionSettings
    ) -> None:
        settings.validate()
        self.structure = structure
        self.settings = settings
        self.paper = settings.paper_rules
        fx, fy, cx, cy = settings.intrinsics
        width, height = settings.intrinsics_size
        self.camera = PinholeCamera(fx, fy, cx, cy, int(width), int(height))
        self.mount = CameraMount(tuple(settings.camera_xyz), tuple(settings.camera_rpy))  # type: ignore[arg-type]
        self.evidence_settings = settings.evidence()
        self.misplacement_settings = settings.misplacement()
        self.robot_settings = settings.robot_mask()
        self.tile_shapes = {name: kind.shape for name, kind in structure.tile_types.items()}
        self._look_alikes: dict[int, list[PlacedTile]] = {}  # tile id: its look-alike rivals, at its pose
        self._rival_scenes: dict[tuple[int, str], VirtualScene] = {}  # (tile id, type): that type alone there
        self.structure_top = float(structure.bounds[1][2])
        self._models: dict[tuple[int, ...], ExpectedModel] = {}
        self.in_hand: frozenset[int] = frozenset()
        self.model = self._model_for(structure.tile_ids if expected is None else expected)
        self.aligning = self.model

    @property
    def expected_ids(self) -> tuple[int, ...]:
        """S_a: the tiles judged (tiles in hand aside)."""
        return tuple(t for t in self.model.tile_ids if t not in self.in_hand)

    def set_expected(self, expected: Iterable[int], in_hand: Iterable[int] = ()) -> None:
        """Change S_a (models are cached per S_a, so going back and forth is cheap). Tiles `in_hand`
        (a robot is placing them: `tiles_in_hand`) may be there or not: the model judged against
        holds them (they may hide others), the result says nothing about them, and the alignment
        leaves them out (`aligning`): mostly they are not there yet, and two of them beside a
        small S_a slid its fit by a tile's width onto their places."""
        expected = set(expected) & set(self.structure.tiles)
        self.in_hand = frozenset(set(in_hand) & set(self.structure.tiles)) - expected
        self.model = self._model_for(expected | self.in_hand)
        self.aligning = self._model_for(expected) if self.in_hand and expected else self.model

    def _model_for(self, expected: Iterable[int]) -> ExpectedModel:
        key = tuple(sorted(set(expected) & set(self.structure.tiles)))
        if key not in self._models:
            if len(self._models) >= 8:
                self._models.pop(next(iter(self._models)))
            self._models[key] = ExpectedModel(self.structure, key, self.settings)
        return self._models[key]

    # ----------------------------------------------------------------------------------------------
    def inspect(
        self, cloud: NDArray[np.float32], overhead: OverheadPose, robots: Sequence[OverheadPose] = (),
        stop_requested: Callable[[], bool] | None = None,
    ) -> ScanResult:
        """Classify every tile of S_a from one organized cloud, the overhead pose of its time and
        the overhead poses of the other robots (default mode: their points are left out).
        `stop_requested` is asked between stages; once it says yes, `InspectionStoppedError` is raised."""
        result = self._inspect(cloud, overhead, robots, stop_requested).without(self.in_hand)
        return result if self.paper else _unless_alone_in_place(result)

    def _inspect(
        self, cloud: NDArray[np.float32], overhead: OverheadPose, robots: Sequence[OverheadPose],
        stop_requested: Callable[[], bool] | None,
    ) -> ScanResult:
        scan, failure = self._start(cloud, overhead, stop_requested)
        if scan is None:
            return failure
        if robots and not self.paper:
            scan.robots = RobotBoxes(robots, self.robot_settings)
        level = self._level_with_floor(scan)
        if not self.paper:
            self._mask_tall_things(scan, level)
        starts, failure = self._search_x_y_yaw(scan, level)
        if failure:
            return scan.failed(self._hidden_by_robots(scan, level) or failure)
        results = [self._classify_from(scan, start) for start in starts]
        rivals = distinct(results)
        if not results[0].ok:  # the best fit's alignment fails its checks: a rival alone is no better
            hidden = self._hidden_by_robots(scan, level) if results[0].reason.startswith("alignment") else ""
            return scan.failed(hidden) if hidden else self._align_leaving_one_out(scan, level, results[0])
        if len(rivals) > 1:
            settled = self._settle_rivals(scan, rivals)
            if settled is None:
                return self._unless_all_moved(self._agreed(rivals), scan)
            rivals = [settled]
        result = rivals[0]
        if self.paper or not result.moved_tiles():
            return result
        return self._judge_again_without_moved_tiles(scan, level=level, first=result)

    # -- stages -----------------------------------------------------------------------------------
    def _start(self, cloud: NDArray[np.float32], overhead: OverheadPose,
               stop_requested: Callable[[], bool] | None) -> tuple[_Scan | None, ScanResult]:
        """The scan with the camera of its resolution, or why it cannot be inspected."""
        timer = _Timer(stop_requested)
        problem = _cloud_problem(cloud)
        if problem:
            return None, ScanResult(ok=False, reason=problem, timings=timer.timings)
        try:
            camera = self.camera.at_resolution(cloud.shape[1], cloud.shape[0])
        except ValueError as error:
            return None, ScanResult(ok=False, reason=str(error), timings=timer.timings)
        if len(self.model) == 0:
            note = "S_a is empty: nothing to inspect"
            return None, ScanResult(ok=True, timings=timer.timings, notes=[note])
        mismatch = camera.check_cloud(cloud)  # the driver's x = (u - cx) z / fx must hold
        timer.lap("check")
        scan = _Scan(cloud, camera, camera_prior(overhead, self.mount), timer)
        if mismatch:
            scan.notes.append(mismatch + ": check the intrinsics parameters")
        timer.lap("prior")
        return scan, ScanResult(ok=True)

    def _level_with_floor(self, scan: _Scan) -> Array:
        """The prior with height, roll and pitch from the floor (section 2.2.1, T_f)."""
        floor = fit_floor(
            scan.cloud, scan.prior, self.model.low, self.model.high, FloorSettings(stride=self.settings.floor_stride)
        )
        scan.floor = floor
        scan.timer.lap("floor")
        if floor is None:
            scan.notes.append(
                "floor not found near where the mount predicts it: using the mount's height, roll, pitch"
            )
            return scan.prior
        return correct_pose(scan.prior, floor)

    def _mask_tall_things(self, scan: _Scan, pose: Array) -> None:
        """Pixels of things standing higher than the structure: robots, people (`robot_mask`)."""
        model = self.model
        high = model.high.copy()
        high[2] = max(high[2], self.structure_top)
        scan.masked = tall_things(
            scan.cloud,
            scan.camera,
            pose,
            model.low,
            high,
            reach=self._search_margin(pose),
            floor_clearance=self.settings.floor_clearance,
            settings=self.robot_settings,
        )
        scan.timer.lap("robots")

    def _hidden_by_robots(self, scan: _Scan, pose: Array) -> str:
        """Why a scan that failed to align could not show S_a: the other robots stand in front of
        most of it (seen from `pose`), or "" when they do not (then the alignment's failure stands)."""
        if scan.robots is None or self.paper:
            return ""
        virtual = self._virtual_scan(scan, pose)
        on_s_a = virtual.tile >= 0
        front = self._robots_in_front(scan, virtual, pose)
        if front is None or not on_s_a.any():
            return ""
        share = float(front[on_s_a].mean())
        if share < self.settings.hidden_by_robots:
            return ""
        return f"S_a not in view: the other robots stand in front of {share:.0%} of it"

    def _search_margin(self, pose: Array) -> float:
        """How far around S_a's box points may lie before the x, y, yaw search (prior errors)."""
        s, model = self.settings, self.aligning
        reach = float(np.linalg.norm(0.5 * (model.low + model.high) - pose[:3, 3]))
        return s.box_margin + s.coarse_shift_range + s.coarse_yaw_range * (reach + 0.3)

    def _search_x_y_yaw(self, scan: _Scan, pose: Array, away: _Away | None = None) -> tuple[list[Array], str]:
        """The x, y, yaw corrections of the overhead pose to start ICP from: a coarse search
        (`coarse_alignment`); in default mode its best few hypotheses, each refined by a short ICP,
        the one that puts most points onto S_a's surfaces first, and after it those that put
        nearly as many there from elsewhere (1 cm cells cannot tell a degree of yaw from a
        centimetre of shift, and a view of a few faces has more than one fit: `rival_fits`)."""
        s, model = self.settings, self.aligning
        if not s.coarse_search or model.coarse is None:
            return [pose], ""
        # the 1 cm voxels of the search need no more than every other pixel (default mode)
        stride = 1 if self.paper else 2
        # the floor fit has set the height: the search margin is a sideways one
        near = select_candidates(
            scan.cloud,
            scan.camera,
            pose,
            model.low,
            model.high,
            self._search_margin(pose),
            s.floor_clearance,
            stride,
            height_margin=s.box_margin,
        )
        near = scan.keep(near)
        near = near.subset(
            at_structure_range(near.points, pose[:2, 3], model.low, model.high, s.box_margin + s.coarse_shift_range)
        )
        if away is not None:
            near = near.subset(away.outside(near.points, pose))
        scan.timer.lap("candidates")
        enough = s.min_alignment_points // stride**2
        if len(near) < enough:
            hidden = f"S_a not in view: only {len(near)} points near where it should be"
            return [pose], f"{hidden} (hidden, out of the image, or a wrong overhead pose or camera mount)"
        found = model.coarse.hypotheses(near.points, pose[:3, 3], 1 if self.paper else s.alignment_candidates)
        found = [h for h in found if h.on_surface >= 0.25 and h.on_surface_points >= enough]
        scan.timer.lap("coarse")
        if not found:
            return [pose], "alignment failed: no x/y/yaw puts the scan on S_a"
        starts = [h.correction @ pose for h in found]
        if len(starts) > s.alignment_hypotheses:
            starts = self._most_agreeing(scan, starts)[: s.alignment_hypotheses]
        if len(starts) == 1:
            return starts, ""
        return self._best_fits(scan, starts, near.points, pose)

    def _most_agreeing(self, scan: _Scan, poses: list[Array]) -> list[Array]:
        """`poses`, those whose view of S_a the depth image bears out best first (`view_agreement`:
        1 cm cells cannot tell the poses of a view of a few flat tiles apart; the pixels a pose
        sees through can)."""
        scores = [self._agreement(scan, pose) for pose in poses]
        scan.timer.lap("view agreement")
        return [poses[k] for k in sorted(range(len(poses)), key=lambda k: -scores[k])]

    def _agreement(self, scan: _Scan, pose: Array) -> float:
        """How well the depth image bears out S_a seen from `pose` (`view_agreement`)."""
        s, model = self.settings, self.aligning
        view = DepthView(scan.cloud, scan.camera, scan.masked)
        agreement = view_agreement(view, model.scene, pose, (model.low, model.high), (s.min_range, s.max_range),
                                   self.evidence_settings)
        return agreement.score(s.seen_through_weight)

    def _best_fits(self, scan: _Scan, poses: list[Array], points: Array, pose: Array) -> tuple[list[Array], str]:
        """The pose, of `poses` refined by a short ICP each, that puts most of `points` (map frame
        under `pose`) within a few millimetres of S_a's surfaces, and its rivals: the poses whose
        fits, 3 cm or 2 degrees away, explain the points nearly as well, or the depth image
        (`view_agreement`) at least nearly as well (a view of a few faces of a repetitive structure;
        the best fit moved by one of S_a's periods, `periodicity`, is always tried); or why none can
        be trusted (too few points fit at all)."""
        s = self.settings
        sample = points[:: max(1, math.ceil(len(points) / s.icp_max_points))]
        fits = [fit for fit in (self._short_fit(scan, start, sample, pose) for start in poses) if fit is not None]
        if fits:
            best = max(fits, key=lambda fit: fit[0])[2]
            moved = (self._short_fit(scan, _shifted(best, shift), sample, pose) for shift in self.aligning.shifts)
            fits += [fit for fit in moved if fit is not None]
        scan.timer.lap("hypotheses")
        if not fits:
            return poses[:1], ""
        fits.sort(key=lambda fit: -fit[0])
        count, start, refined = fits[0]
        if count < s.min_fit_points:
            return [start], f"alignment failed: only {count} points fit S_a's surfaces"
        agreement = self._agreement(scan, refined)
        near_agreement = agreement - (1.0 - s.ambiguity) * abs(agreement)
        starts = [start]  # the full ICP starts from the hypotheses, not from these short refinements
        for other, elsewhere, refined_elsewhere in fits[1:]:
            if _apart(refined_elsewhere, refined) and (
                    other >= s.ambiguity * count or self._agreement(scan, refined_elsewhere) >= near_agreement):
                starts.append(elsewhere)
        scan.timer.lap("view agreement")
        return starts, ""

    def _agreed(self, rivals: list[ScanResult]) -> ScanResult:
        """What every rival says (`rival_fits.agreed`), doubted as one alignment's verdicts are: with
        the tiles they disagree on left out, the pixels left must still bear S_a out (three fits up to
        10 cm apart, robots hiding all but two tiles, each passed alone on the tile it sat on; all they
        shared was a present long rectangle seen through, and it was called missing)."""
        result = agreed(rivals)
        if result.evidence is not None:
            result.doubt = result.doubt or self._doubt(result.evidence, result)
        return result

    def _doubt(self, evidence: TileEvidence, result: ScanResult) -> str:
        """Why `evidence` doubts the alignment of `result` (`_doubtful`, with its moved tiles and the
        tiles in hand), or ""."""
        moved = [self.model.tile_ids.index(t) for t in result.moved_tiles()]
        in_hand = [self.model.tile_ids.index(t) for t in self.in_hand]
        return _doubtful(evidence, self.settings, moved, in_hand)

    def _settle_rivals(self, scan: _Scan, rivals: list[ScanResult]) -> ScanResult | None:
        """The alignment from the one rival fit the depth image bears out clearly best once each is
        moved uphill on the view agreement (`view_agreement.climb`), or None while two stay close
        (then only the tiles all rivals agree on are judged)."""
        s = self.settings
        climbed = [climb(r.camera_pose, lambda pose: self._agreement(scan, pose)) for r in rivals]  # type: ignore[arg-type]
        scan.timer.lap("climb")
        best = max(range(len(climbed)), key=lambda k: climbed[k][1])
        pose, score = climbed[best]
        near = score - (1.0 - s.ambiguity) * abs(score)
        if any(k != best and other_score >= near and _apart(other, pose)
               for k, (other, other_score) in enumerate(climbed)):
            return None
        result = self._classify_from(scan, pose)
        if not result.ok or self._agreement(scan, result.camera_pose) < near:  # type: ignore[arg-type]
            return None
        return result

    def _short_fit(self, scan: _Scan, start: Array, sample: Array, pose: Array) -> tuple[int, Array, Array] | None:
        """(points of `sample` within 3 mm of S_a's surfaces, `start`, the pose a short ICP refines
        it to); None when too few of them fall in S_a's box from `start`. (Moved by a period, the
        best fit needs the ICP too: counted as it is, it let twice as many false missing calls by.)"""
        s, model = self.settings, self.aligning
        move = start @ np.linalg.inv(pose)
        moved = sample @ move[:3, :3].T + move[:3, 3]
        inside = np.all((moved >= model.low - s.box_margin) & (moved <= model.high + s.box_margin), axis=1)
        if inside.sum() < 6:
            return None
        refined = self._refine_with_icp(scan, pose=start, points=moved[inside], iterations=5).correction @ start
        move = refined @ np.linalg.inv(pose)
        final = sample @ move[:3, :3].T + move[:3, 3]
        closest, _, _ = model.scene.closest_points(final)
        on_surface = np.einsum("ij,ij->i", final - closest, final - closest) <= 0.003**2
        return int(np.count_nonzero(on_surface)), start, refined

    def _classify_from(self, scan: _Scan, start: Array, suspects: Sequence[int] = ()) -> ScanResult:
        """The alignment from one x, y, yaw hypothesis and the classification under it; the
        pixels it masks as robots are its own (a rival starts from the same masks)."""
        masks = [None if m is None else m.copy() for m in (scan.masked, scan.unjudged, scan.robot_pixels)]
        candidates = self._candidates(scan, start)
        if len(candidates) < self.settings.min_alignment_points:
            result = scan.failed(f"alignment failed: only {len(candidates)} candidate points")
        else:
            result = self._align_and_classify(scan, pose=start, candidates=candidates, suspects=suspects)
        scan.masked, scan.unjudged, scan.robot_pixels = masks
        return result

    def _candidates(self, scan: _Scan, pose: Array) -> Candidates:
        """C_1: points near S_a's box, above the floor, not of a robot (inside a robot's box, grown by
        its localization error, and off S_a's surfaces); masks the robots' pixels."""
        s, model = self.settings, self.model
        candidates = select_candidates(
            scan.cloud, scan.camera, pose, model.low, model.high, s.box_margin, s.floor_clearance
        )
        if scan.robots is not None:
            self._mask_robot_points(scan, candidates)
        scan.timer.lap("candidates")
        return scan.keep(candidates)

    def _mask_robot_points(self, scan: _Scan, candidates: Candidates) -> None:
        """Masks the candidates inside a robot's grown box and off S_a's surfaces. Those on S_a's
        surfaces help the alignment, but no tile is judged on the ones beside the robot's own
        points (a robot's body can pass for the faces of a tile that is gone)."""
        s = self.settings
        robot = inside_robots(candidates.points, scan.robots.robots, self.robot_settings)  # type: ignore[union-attr]
        if not robot.any():
            return
        inside = np.flatnonzero(robot)
        closest, _, _ = self.model.scene.closest_points(candidates.points[inside])
        gap = candidates.points[inside] - closest
        on_surface = inside[np.einsum("ij,ij->i", gap, gap) <= s.robot_surface_gap**2]
        robot[on_surface] = False
        beside = on_surface[
            near_robot_points(candidates.points[on_surface], candidates.points[robot], s.robot_face_reach)
        ]
        if scan.masked is None:
            scan.masked = np.zeros(scan.cloud.shape[:2], dtype=bool)
        if scan.robot_pixels is None:
            scan.robot_pixels = np.zeros(scan.cloud.shape[:2], dtype=bool)
        pixels = candidates.pixels[robot]
        scan.robot_pixels.reshape(-1)[pixels[~scan.masked.reshape(-1)[pixels]]] = True  # not masked otherwise
        scan.masked.reshape(-1)[pixels] = True
        if scan.unjudged is None:
            scan.unjudged = np.zeros(scan.cloud.shape[:2], dtype=bool)
        scan.unjudged.reshape(-1)[candidates.pixels[beside]] = True

    def _align_and_classify(
        self,
        scan: _Scan,
        pose: Array,
        candidates: Candidates,
        judged: Candidates | None = None,
        suspects: Sequence[int] = (),
        motions: Mapping[int, Motion] | None = None,
    ) -> ScanResult:
        """ICP of `candidates` (and the floor) from `pose`, the checks, the virtual scan and the
        classification. `judged`: the candidates to judge placement on, when ICP used fewer;
        `suspects`: tiles (indices) found misplaced before, refitted whatever the first step says;
        `motions`: the motions found for some of them then, put to the pixels again should the
        refit now find another."""
        icp = self._refine_with_icp(scan, pose=pose, points=candidates.points)
        scan.timer.lap("icp")
        pose = icp.correction @ pose
        placed = (judged or candidates).moved(icp.correction)
        nearest = None if self.paper else self._nearest_on_structure(placed, used=candidates)
        failure = self._check_alignment(scan, pose=pose, icp=icp, candidates=candidates, nearest=nearest)
        if failure:
            return scan.failed(failure)
        virtual = self._virtual_scan(scan, pose)
        masked = _either(scan.masked, scan.unjudged)
        masked = None if masked is None else masked[virtual.rows, virtual.cols]
        against_blank = None
        if not self.paper:
            virtual = self.model.scene.look_behind(
                virtual, scan.camera, pose, where=judgeable(virtual, self.evidence_settings, masked)
            )
            scan.timer.lap("look behind")
            scan.virtual = (pose.tobytes(), virtual)
            robots = self._robots_in_front(scan, virtual, pose)
            unknown = masked if robots is None else robots if masked is None else masked | robots
            against_blank = self._blanks_against_tiles(scan, virtual, pose, unknown)
        evidence = pixel_evidence(
            scan.cloud, virtual, len(self.model), self.evidence_settings, against_blank, masked
        )
        scan.timer.lap("evidence")
        result = ScanResult(
            ok=True,
            camera_pose=pose,
            alignment_rms=icp.rms,
            candidates=len(candidates),
            timings=scan.timer.timings,
            notes=scan.notes,
            tile_ids=self.model.tile_ids,
        )
        if self.paper:
            self._classify_paper(placed, virtual, pose, result)
            scan.timer.lap("classify")
        else:
            self._classify_by_evidence(evidence, result, pose)
            scan.timer.lap("classify")
            assert nearest is not None
            held_back = self._judge_placement(nearest[0], pose, result, suspects, scan, motions or {})
            result = untold(result, held_back)
            scan.timer.lap("misplacement")
        doubt = self._doubt(evidence, result)
        if doubt and not result.moved_tiles():  # with tiles found moved, the alignment without them decides
            return scan.failed(f"alignment doubtful: {doubt}")
        result.doubt = doubt
        return result

    def _refine_with_icp(self, scan: _Scan, pose: Array, points: Array, iterations: int = 0) -> IcpResult:
        """Point-to-plane ICP of candidate `points` (map frame under `pose`) against S_a and of the
        floor sample against the floor; at most `iterations` (0: the setting's)."""
        s = self.settings
        if self.paper:
            structure_points = points
        else:
            structure_points = points[:: max(1, math.ceil(len(points) / s.icp_max_points))]
        floor = scan.floor
        floor_points = np.zeros((0, 3)) if floor is None else floor.sample @ pose[:3, :3].T + pose[:3, 3]
        on_structure = self._correspondences(pose[:3, 3].copy())
        count = len(structure_points)

        def correspond(points: Array, cut: float) -> Correspondences:
            structure = on_structure(points[:count], cut)
            on_floor = points[count:]
            return Correspondences(
                np.vstack([structure.closest, on_floor * np.array([1.0, 1.0, 0.0])]),
                np.vstack([structure.normal, np.tile([0.0, 0.0, 1.0], (len(on_floor), 1))]),
                np.concatenate([structure.distance, np.abs(on_floor[:, 2])]),
            )

        icp = point_to_plane_icp(
            np.vstack([structure_points, floor_points]),
            correspond,
            IcpSettings(max_iterations=iterations or s.icp_max_iterations),
        )
        return icp

    def _correspondences(self, camera_position: Array) -> Callable[[Array, float], Correspondences]:
        """Projections onto S_a: the paper's patch hierarchy (faces turned away left out) in paper
        mode; Open3D's BVH closest points in default mode (same answer, a fraction of the time)."""
        model = self.aligning
        if self.paper:

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

    def _nearest_on_structure(self, placed: Candidates, used: Candidates) -> tuple[ScanPoints, Mask]:
        """One closest-point query on S_a for a sample of the aligned candidates, for the alignment
        check and the misplacement; and which of them ICP used."""
        sample = placed.subset(slice(None, None, max(1, math.ceil(len(placed) / self.settings.misplacement_points))))
        closest, normals, nearest_tile = self.model.scene.closest_points(sample.points)
        points = ScanPoints(sample.points, sample.optical[:, 2], nearest_tile, closest, normals)
        return points, np.isin(sample.pixels, used.pixels)

    def _check_alignment(
        self,
        scan: _Scan,
        pose: Array,
        icp: IcpResult,
        candidates: Candidates,
        nearest: tuple[ScanPoints, Mask] | None,
    ) -> str:
        """Why the aligned pose is not believable, or "": enough of the points ICP used on S_a, and a
        correction of the overhead pose within its error bounds."""
        s = self.settings
        if nearest is None:  # paper mode: the patch hierarchy on every candidate
            icp_points = candidates.points @ icp.correction[:3, :3].T + icp.correction[:3, 3]
            distance = self._correspondences(pose[:3, 3])(icp_points, 0.01).distance
        else:
            points, used = nearest
            gap = points.points - points.closest
            distance = np.sqrt(np.einsum("ij,ij->i", gap, gap))[used]
        inliers, points = int(np.count_nonzero(distance <= 0.01)), len(distance)
        scan.timer.lap("check alignment")
        if inliers < s.min_alignment_points or inliers < s.min_alignment_inliers * points:
            return f"alignment failed: ICP kept only {inliers} of {points} points on S_a"
        shift = float(np.linalg.norm(pose[:2, 3] - scan.prior[:2, 3]))
        turn = abs(_yaw(pose) - _yaw(scan.prior))
        turn = min(turn, 2 * math.pi - turn)
        if shift > s.max_pose_correction or turn > s.max_yaw_correction:
            return (
                f"alignment failed: the correction of the overhead pose ({shift * 100:.0f} cm, "
                f"{math.degrees(turn):.0f} deg) is beyond belief"
            )
        return ""

    def _virtual_scan(self, scan: _Scan, pose: Array) -> VirtualScan:
        """C_v over the window that sees S_a; default mode: with what lies behind every tile."""
        model = self.model
        rows, cols = scan.camera.box_roi(pose, model.low, model.high)
        virtual = model.scene.cast(scan.camera, pose, rows, cols, self.settings.min_range, self.settings.max_range)
        scan.timer.lap("raycast")
        return virtual

    def _robots_in_front(self, scan: _Scan, virtual: VirtualScan, pose: Array) -> Mask | None:
        """Window pixels where a robot the overhead cameras see may stand in front of S_a: a blank
        there may be the robot's (nearer than the camera's range, or its projector shadow). Where
        the camera measured something, the measurement tells whether the robot is really there."""
        if scan.robots is None:
            return None
        directions = scan.camera.rays[virtual.rows, virtual.cols] @ pose[:3, :3].T.astype(np.float32)
        return scan.robots.depth(pose[:3, 3], directions) < virtual.depth

    def _blanks_against_tiles(self, scan: _Scan, virtual: VirtualScan, pose: Array, robots: Mask | None) -> Mask:
        """Blank pixels that only "the tile is gone" explains (`expected_returns`, `blank_evidence`);
        `robots`: pixels of robots, measured or where the overhead cameras put them."""
        depth = scan.cloud[..., 2]
        blank = ~np.isfinite(depth[virtual.rows, virtual.cols])  # only blanks need the returns
        returns = expect_returns(
            virtual, self.model.scene, scan.camera, pose, self.evidence_settings.returns, where=blank
        )
        scan.timer.lap("expected returns")
        other = unexpected(scan.cloud, virtual, self.evidence_settings)
        against = blank_evidence(
            depth,
            virtual,
            returns,
            scan.camera,
            self.evidence_settings.returns.projector_offset,
            other if robots is None else other | robots,
            smooth(virtual.depth),
        )
        scan.timer.lap("blank evidence")
        return against

    # -- classification ---------------------------------------------------------------------------
    def _classify_paper(self, placed: Candidates, virtual: VirtualScan, pose: Array, result: ScanResult) -> None:
        """p_i, v_i and the paper's rules (section 2.2.3, `classify.paper_support`)."""
        s = self.settings
        counts = paper_support(
            patches=self.model.patches,
            points=placed.points,
            virtual=virtual,
            rays=self.camera.at_resolution(*virtual.size).rays,
            pose=pose,
            support_distance=s.support_distance,
            floor_clearance=s.floor_clearance,
            min_support=s.min_support,
            ratio_threshold=s.ratio_threshold,
        )
        evidence = TileEvidence.zeros(len(self.model))
        evidence.agree, evidence.virtual = counts.physical, counts.virtual
        result.evidence, result.evidence_states = evidence, counts.states
        result.tiles = [
            TileResult(
                tile_id=int(tile_id),
                state=TileState(int(counts.states[k])),
                physical=int(counts.physical[k]),
                virtual=int(counts.virtual[k]),
                ratio=float(counts.ratio[k]),
                residual=float(counts.residual[k]),
            )
            for k, tile_id in enumerate(self.model.tile_ids)
        ]

    def _classify_by_evidence(self, evidence: TileEvidence, result: ScanResult, pose: Array) -> None:
        """Decide every tile from its pixel evidence, relative to what the virtual scan predicts for it
        (nothing against the tiles too deep in the camera's view to tell them gone, `too_deep`)."""
        depth = (self.model.patches.tile_centroid - pose[:3, 3]) @ pose[:3, 2]
        evidence = evidence.unopposed(too_deep(depth, self.evidence_settings))
        states = decide(evidence, self.evidence_settings)
        result.evidence, result.evidence_states = evidence, states
        observed = np.maximum(evidence.observed, 1)
        result.tiles = [
            TileResult(
                tile_id=int(tile_id),
                state=TileState(int(states[k])),
                physical=int(evidence.agree[k]),
                virtual=int(evidence.virtual[k]),
                ratio=float(evidence.agree[k] / observed[k]),
                see_through=int(evidence.see_through[k]),
                in_front=int(evidence.in_front[k]),
                no_return=int(evidence.no_return[k]),
                judged=int(evidence.judged[k]),
                blank=int(evidence.blank[k]),
                ambiguous=int(evidence.ambiguous[k]),
            )
            for k, tile_id in enumerate(self.model.tile_ids)
        ]

    def _judge_placement(
        self, points: ScanPoints, pose: Array, result: ScanResult, suspects: Sequence[int], scan: _Scan,
        motions: Mapping[int, Motion],
    ) -> list[int]:
        """Per-tile residuals, and MISPLACED for tiles whose points a planar motion explains better
        and whose pixels agree, or whose pixels say something of another shape lies there
        (`misplacement`); or for a tile whose earlier motion (`motions`) its pixels still bear out
        when the refit from the new alignment finds another (a 4 cm square shifted 5 cm: 292 of its
        pixels agreed at the first fit, 8 at the second). Returns the tiles whose pixels agree but
        whose points lean towards a motion: not shown in place."""
        model = self.model
        held_back = []
        fits = assess(
            points,
            PlacementContext(
                patches=model.patches,
                camera_position=pose[:3, 3],
                tiles=model.tiles,
                surfaces=model.scene,
                solid=[t.state != TileState.MISSING for t in result.tiles],
                disturbed=[t.see_through + t.in_front >= 1 for t in result.tiles],
                # blanks where a return was due count against a tile too: a cap turned 25 degrees had
                # 10 pixels in front of its faces and 11 such blanks, and its first step was 1.5 degrees
                suspects=(*suspects, *self._disturbed_tiles(result, blank=True)),
                by_robots=None if scan.robots is None else inside_robots(
                    points.points, scan.robots.robots, self.robot_settings),
            ),
            self.misplacement_settings,
        )
        for index, fit in fits.items():
            tile = result.tiles[index]
            tile.residual = fit.residual
            misplaced = confirmed_by_pixels(
                fit,
                agree=tile.physical,
                see_through=tile.see_through,
                in_front=tile.in_front,
                blank=tile.blank,
                settings=self.misplacement_settings,
            ) or (fit.misplaced and self._fitted_pose_explains(scan, pose, index, fit.offset, tile.physical))
            offset = fit.offset
            if not misplaced and index in motions and tile.state is not TileState.PRESENT:
                misplaced = self._fitted_pose_explains(scan, pose, index, motions[index], tile.physical)
                offset = motions[index] if misplaced else offset
            if fit.judged or offset != fit.offset:
                result.misplacement[tile.tile_id] = (misplaced, offset, fit.residual)
            if misplaced:
                tile.state, tile.offset = TileState.MISPLACED, offset
            elif tile.state in (TileState.OCCLUDED, TileState.PRESENT) and (
                    something_else_there(fit, self.misplacement_settings)
                    or (tile.state is TileState.OCCLUDED and other_shape(
                        tile.physical, tile.see_through + tile.blank, self.misplacement_settings, fit.resolution))):
                tile.state, tile.offset = TileState.MISPLACED, (0.0, 0.0, 0.0)
                result.misplacement[tile.tile_id] = (True, tile.offset, fit.residual)
            elif tile.state is TileState.PRESENT and (fit.misplaced or fit.unresolved or hinted_motion(
                    fit, model.tiles[index], self.misplacement_settings)):
                # its points moved (or within the noise), its pixels cannot tell: no verdict rather
                # than "present and in place", and no pixels for fusion to add up to one either (a
                # square turned 16 degrees, held back by every scan, was fused present from their sum)
                held_back.append(tile.tile_id)
        for index in self._disturbed_tiles(result, blank=True):
            tile = result.tiles[index]
            if tile.state is TileState.MISPLACED:
                continue
            tile.seen_type = self._another_type_explaining(scan, pose, index)
            if tile.seen_type:
                tile.state, tile.offset = TileState.MISPLACED, (0.0, 0.0, 0.0)
                result.misplacement[tile.tile_id] = (True, tile.offset, tile.residual)
        held_back += [
            tile.tile_id for index, tile in enumerate(result.tiles)
            if tile.state is TileState.PRESENT and tile.tile_id not in held_back
            and (too_little_seen(decisive=tile.physical + tile.see_through + tile.blank, judged=tile.judged,
                                 expected=tile.virtual, settings=self.misplacement_settings)
                 or self._another_type_as_likely(scan, pose, index))
        ]
        return [t for t in held_back if result.by_id()[t].state is not TileState.MISPLACED]

    def _fitted_pose_explains(self, scan: _Scan, pose: Array, index: int, offset: tuple[float, float, float],
                              planned_agree: int) -> bool:
        """Whether the depth image bears out a refit its pixels at the planned pose cannot confirm
        (little of a tile that slipped far still covers its place): `pose_hypotheses`. The pixels
        left out only for lying in a robot's grown box count here: a tile that slipped towards a
        robot lies in that box, off S_a's surfaces (a wedge shifted 2.7 cm beside a robot had 350 of
        its 517 pixels there, and was called missing). The refit stands on points outside the box,
        and a robot's face does not take the shape of the tile at its fitted pose."""
        settings = self.misplacement_settings
        window = scan.camera.box_roi(pose, self.model.low, self.model.high)
        masked = scan.masked
        if masked is not None and scan.robot_pixels is not None:
            masked = masked & ~scan.robot_pixels
        masked = _either(masked, scan.unjudged)
        image = DepthImage(scan.cloud, scan.camera, pose, window, None if masked is None else masked[window])
        fitted = pixels_at_fitted_pose(self.model.tiles, index, offset, image, self.evidence_settings,
                                       (self.settings.min_range, self.settings.max_range))
        return fitted_pose_explains(planned_agree, fitted, settings.fitted_share, settings.fitted_gain,
                                    settings.fitted_pixels)

    def _disturbed_tiles(self, result: ScanResult, blank: bool = False) -> list[int]:
        """Tiles (indices) whose pixels disagree with their planned pose on a good share: refitted
        whatever the first linearised step says, which underestimates a turn of 15 degrees or more
        (a block of pyramid_91 turned 30 degrees stepped 3). `blank`: blanks against it disagree too."""
        settings = self.misplacement_settings
        disturbed = []
        for k, t in enumerate(result.tiles):
            against = t.see_through + t.in_front + (t.blank if blank else 0)
            if against >= max(settings.disturbed_pixels, settings.disturbed_share * (t.physical + against)):
                disturbed.append(k)
        return disturbed

    def _another_type_explaining(self, scan: _Scan, pose: Array, index: int) -> str:
        """The type of a tile that, at the tile's planned pose, explains its pixels clearly better than
        the planned type (`type_hypotheses`: a robot took a tile from the wrong cache), or ""."""
        settings = self.misplacement_settings
        rivals = rival_tiles(self.model.tiles[index], self.tile_shapes)
        for rival, votes in self._type_votes(scan, pose, index, rivals):
            if votes.rival_explains(settings.rival_share, settings.rival_pixels):
                return rival.type_name
        return ""

    def _another_type_as_likely(self, scan: _Scan, pose: Array, index: int) -> bool:
        """Whether a tile of a look-alike type (`type_hypotheses.look_alike_rivals`) at the tile's
        planned pose explains the pixels where the two differ as well as the planned one: then the
        tile is not shown in place. A square where a triangle was planned covers the triangle: all 60
        of the triangle's pixels agreed, and the square's corners beyond it, 7-17 pixels, were all
        the pixels that could tell."""
        settings = self.misplacement_settings
        tile = self.model.tiles[index]
        if tile.tile_id not in self._look_alikes:
            self._look_alikes[tile.tile_id] = look_alike_rivals(tile, self.tile_shapes, settings.look_alike)
        votes = self._type_votes(scan, pose, index, self._look_alikes[tile.tile_id])
        return any(vote.rival_as_likely(settings.rival_doubt_pixels) for _, vote in votes)

    def _type_votes(self, scan: _Scan, pose: Array, index: int,
                    rivals: Sequence[PlacedTile]) -> Iterator[tuple[PlacedTile, TypeVotes]]:
        """Tile `index` as planned against each of `rivals` in its place, one at a time
        (`type_hypotheses`)."""
        for rival in rivals:
            voted = (pose.tobytes(), index, rival.type_name)
            if voted not in scan.type_votes:
                scan.type_votes[voted] = self._votes_against(scan, pose, index, rival)
            yield rival, scan.type_votes[voted]

    def _votes_against(self, scan: _Scan, pose: Array, index: int, rival: PlacedTile) -> TypeVotes:
        """The type votes between tile `index` as planned and `rival` in its place, from `pose`."""
        model = self.model
        masked = _either(scan.masked, scan.unjudged)
        window = scan.camera.box_roi(pose, *tiles_box([model.tiles[index], rival]))
        image = DepthImage(scan.cloud, scan.camera, pose, window, None if masked is None else masked[window])
        alone = (rival.tile_id, rival.type_name)
        if alone not in self._rival_scenes:
            self._rival_scenes[alone] = VirtualScene([rival])
        cast = None
        if scan.virtual is not None and scan.virtual[0] == pose.tobytes():
            # what lies behind all of the tile, looked at once for all its rivals
            whole = model.scene.complete_behind(scan.virtual[1], scan.camera, pose, where=scan.virtual[1].tile == index)
            scan.virtual = (scan.virtual[0], whole)
            cast = whole.within(*window)
        return type_votes(model.scene, index, rival, image, self.evidence_settings,
                          (self.settings.min_range, self.settings.max_range), self._rival_scenes[alone], cast)

    def _align_leaving_one_out(self, scan: _Scan, level: Array, failed: ScanResult) -> ScanResult:
        """A scan that fails to align may be pulled off by one misplaced tile: with few tiles in S_a a
        long rectangle turned 23 degrees drew every fit 10-18 cm and up to 22 degrees off the overhead
        pose, and the scans gave no states until a removal took the tile away. Align once more without
        each of the largest tiles in turn (its points stay in the scan, as clutter) and judge it as a
        suspect; the first of its fits that passes its checks stands if it finds that tile moved (then
        as any scan that finds a tile moved: `_unless_all_moved`). Otherwise the failure stands."""
        if self.paper or not failed.reason.startswith("alignment") or len(self.aligning) < 2:
            return failed
        aligning = self.aligning
        extent = aligning.patches.tile_high[:, :2] - aligning.patches.tile_low[:, :2]
        largest = np.argsort(-extent.prod(axis=1), kind="stable")[:LEAVE_OUT_TRIES]
        try:
            for index in largest:
                tile_id = aligning.tile_ids[index]
                self.aligning = self._model_for(set(aligning.tile_ids) - {tile_id})
                starts, failure = self._search_x_y_yaw(scan, level)
                suspects = [self.model.tile_ids.index(tile_id)]
                fits = (self._classify_from(scan, start, suspects) for start in ([] if failure else starts))
                result = next((fit for fit in fits if fit.ok), None)
                if result is not None and tile_id in result.moved_tiles():
                    result.notes = [*result.notes, f"aligned without tile {tile_id}: {failed.reason}"]
                    # every fit with the tile in place failed its checks, so one tile judged in place
                    # beside it tells it from a misalignment (`_unless_unanchored`)
                    return self._unless_all_moved(result, scan, anchors=1)
        finally:
            self.aligning = aligning
        return failed

    def _judge_again_without_moved_tiles(self, scan: _Scan, level: Array, first: ScanResult) -> ScanResult:
        """A misplaced tile pulls the alignment towards where it lies: search and align once more,
        from the floor-levelled prior, without the points around the tiles found misplaced, and
        judge everything again."""
        assert first.camera_pose is not None
        model = self.model
        moved = first.moved_tiles()
        boxes = []
        for tile_id in moved:
            index = model.tile_ids.index(tile_id)
            offset = first.misplacement[tile_id][1]
            reach = self.misplacement_settings.reach + math.hypot(offset[0], offset[1])
            boxes.append((model.patches.tile_low[index] - reach, model.patches.tile_high[index] + reach))
        away = _Away(first.camera_pose, boxes)
        starts, failure = self._search_x_y_yaw(scan, level, away)
        if failure or len(starts) > 1:
            return self._unless_all_moved(first, scan)
        pose = starts[0]
        candidates = self._candidates(scan, pose)
        keep = away.outside(candidates.points, pose)
        if keep.sum() < self.settings.min_alignment_points:
            return self._unless_all_moved(first, scan)
        second = self._align_and_classify(
            scan,
            pose=pose,
            candidates=candidates.subset(keep),
            judged=candidates,
            suspects=[model.tile_ids.index(t) for t in moved],
            motions={model.tile_ids.index(t): first.misplacement[t][1] for t in moved if any(first.misplacement[t][1])},
        )
        return self._unless_all_moved(second if second.ok else first, scan)

    def _unless_all_moved(self, result: ScanResult, scan: _Scan, anchors: int = 2) -> ScanResult:
        """No states from a scan in which several tiles seem moved: a misalignment is far more likely
        than three tiles misplaced at once, or two that moved as one (`moved_as_one`), or two moved
        beside as many called missing with fewer than two tiles in place to anchor the alignment (or
        the whole structure was pushed: S_a no longer fits); nor from one whose pixels doubt the
        alignment. Two tiles that each moved their own way, or two of another type, in a scan that
        finds tiles in place, are two misplaced tiles."""
        if result.ok and result.doubt:
            return scan.failed(f"alignment doubtful: {result.doubt}")
        judged = len(result.misplacement)
        moved = result.moved_tiles()
        if len(moved) == 1:
            return self._unless_unanchored(result, moved[0], anchors)
        if len(moved) < 2 or len(moved) < 0.25 * judged:
            return result
        together = f"alignment doubtful: {len(moved)} of {judged} tiles seem moved together"
        offsets = [result.misplacement[t][1] for t in moved]
        centroids = [self.model.tiles[self.model.tile_ids.index(t)].centroid for t in moved]
        if len(moved) > 2 or moved_as_one(offsets, centroids, self.misplacement_settings):
            return scan.failed(together)
        states = [t.state for t in result.tiles]
        missing, anchors = states.count(TileState.MISSING), states.count(TileState.PRESENT)
        if missing + len(moved) >= 0.5 * (len(states) - states.count(TileState.OCCLUDED)) and anchors < 2:
            return scan.failed(f"alignment doubtful: {len(moved)} tiles seem moved and {missing} missing")
        return result

    def _unless_unanchored(self, result: ScanResult, moved: int, needed: int = 2) -> ScanResult:
        """A tile found moved with fewer than `needed` tiles judged in place beside it: the alignment rests
        on those few, so the scan cannot tell the tile moved from the tile under the alignment moved
        (and the scan with it). Neither is judged (`rival_fits.untold`), rather than the wrong one
        flagged and the moved one shown in place: a block shifted 2.9 cm on the block under it, the
        other pier gone, took the alignment with it, and the block in place was flagged. A tile
        another shape lies in the place of is told by its pixels, not by a motion: its flag stands."""
        offset = result.misplacement[moved][1]
        if not any(offset):
            return result
        anchors = [t.tile_id for t in result.tiles if t.state is TileState.PRESENT and t.tile_id in result.misplacement]
        if len(anchors) >= needed:
            return result
        beside = f"only tile {anchors[0]}" if anchors else "no tile"
        return untold(result, [moved, *anchors], f"tile {moved} seems moved, with {beside} judged in place "
                      "beside it to tell it from a misalignment: left undetermined")


def _unless_alone_in_place(result: ScanResult) -> ScanResult:
    """A scan that shows one tile only in place cannot tell it in place: the alignment rests on that
    tile, and within the overhead pose's errors a tile a few centimetres off its place takes the
    camera's pose with it. It is left undetermined (`rival_fits.untold`); the other tiles' verdicts
    stand. Independent scenes: a block shifted 2.3 cm, alone in view past two robots, aligned 3.1 cm
    off and was called present; so was a long rectangle lying where a square was planned, the one
    tile a view past a robot showed, onto which the alignment slid the square 6.6 cm."""
    if not result.ok:
        return result
    in_place = [t.tile_id for t in result.tiles if t.state is TileState.PRESENT]
    if len(in_place) != 1:
        return result
    return untold(result, in_place, f"tile {in_place[0]} is the only tile in place in view, and the alignment "
                  "rests on it: not shown in place")


def _either(first: Mask | None, second: Mask | None) -> Mask | None:
    if first is None or second is None:
        return first if second is None else second
    return first | second


def _doubtful(evidence: TileEvidence, settings: InspectionSettings, moved: Sequence[int] = (),
              in_hand: Sequence[int] = ()) -> str:
    """Why the pixel evidence says the scan is misaligned, or "". The pixels measured where S_a has
    a surface (agreeing with a tile, or fitting both "there" and "gone") show the alignment fits. A
    scan that contradicts most of what S_a predicts is misaligned (a fragment of the structure
    fitted to the wrong place), unless at least two tiles clearly fit to anchor it (then most of S_a
    is simply gone). The pixels of tiles found `moved` (by index) count against, not for it: a scan
    4.6 cm off showed little but a long rectangle, which it fitted and then called another shape,
    and called the two tiles beside it missing. A scan in which several tiles are each partly there
    and partly not is misaligned too: a tile is there or gone, and one moved tile splits one tile,
    not several (the tiles `moved` are left out of this; the tiles `in_hand`, by index, of both
    checks: they may not be there yet)."""
    fits = evidence.agree + evidence.ambiguous
    seen = fits + evidence.against
    fits[list(in_hand)], seen[list(in_hand)] = 0, 0
    fits[list(moved)] = 0  # a tile found off its place cannot vouch for the alignment
    anchors = (fits >= 4 * settings.min_observed_pixels) & (fits >= settings.present_fraction * seen)
    if seen.sum() >= settings.min_observed_pixels and fits.sum() < settings.min_agreement * seen.sum():
        if anchors.sum() < 2:
            return f"the scan agrees with only {fits.sum() / seen.sum():.0%} of what S_a predicts"
    decisive = evidence.observed >= settings.min_observed_pixels
    decisive[list(moved) + list(in_hand)] = False
    split = decisive & (np.minimum(evidence.agree, evidence.against) >= 0.25 * evidence.observed)
    if split.sum() >= 2 and split.sum() >= 0.25 * decisive.sum():
        return f"{int(split.sum())} of {int(decisive.sum())} tiles seen are each partly there and partly not"
    return ""


def _cloud_problem(cloud: object) -> str:
    """Why `cloud` is not an organized cloud with data, or ""."""
    if not isinstance(cloud, np.ndarray) or cloud.ndim != 3 or cloud.shape[2] != 3:
        shape = getattr(cloud, "shape", None)
        return f"bad cloud: expected an organized (H, W, 3) array, got shape {shape}"
    if cloud.shape[0] < 2 or cloud.shape[1] < 2:
        return f"bad cloud: {cloud.shape[1]}x{cloud.shape[0]} is not an organized image"
    if np.count_nonzero(np.isfinite(cloud[::4, ::4, 2])) == 0:
        return "bad cloud: no valid points (all NaN or empty)"
    return ""


def _apart(pose: Array, other: Array) -> bool:
    """Whether two fits of a scan are rivals rather than one: 3 cm or 2 degrees apart."""
    shift, turn = pose_error(pose, other)
    return shift > 0.03 or turn > math.radians(2.0)


def _shifted(pose: Array, shift: Array) -> Array:
    """`pose` moved by the horizontal `shift` (x, y) in the map frame."""
    moved = pose.copy()
    moved[:2, 3] += shift
    return moved


def _yaw(pose: Array) -> float:
    return rpy_from_rotation(pose[:3, :3] @ OPTICAL_FROM_LINK.T)[2]
