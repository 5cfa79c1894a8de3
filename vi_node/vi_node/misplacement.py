"""Misplaced tiles: points that sit consistently off a tile's expected faces (beyond the paper; its
section 5 names "identification of incorrect assembly placements" as future work).

After the scan is aligned to S_a, every candidate point is given to its nearest expected tile (if
within a few centimetres). A tile whose points are, in a good share, farther from its faces than
the sensor noise allows is refitted on its own: a planar rigid motion (x, y and a turn about its
vertical axis, the way a tile slips when placed) that puts its points back onto its expected faces.
If that motion is large enough (default: 1 cm or 8 degrees) and explains the points much better,
the tile is flagged, with the motion as its offset, unless the motion is smaller than the camera
resolves at the tile's depth (`depth_noise`: 1.2 cm at 2 m, 2.7 cm at 3 m); then it is "unresolved",
neither misplaced nor shown in place. So is a tile whose refit finds a clear motion of at least 0.6
of a flag's size that stays short of a flag. The per-tile residual (RMS distance of its points to its
faces) is reported for every tile.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.contacts import separation
from tiling_assembly.geometry import PlacedTile, rotation_from_rpy
from vi_node.depth_noise import resolved_motion
from vi_node.patches import PlanarPatches, Projection

Array = NDArray[np.float64]


@dataclass(frozen=True)
class MisplacementSettings:
    shift: float = 0.015  # m, flag when the fitted offset of the tile exceeds this ...
    turn: float = 0.175  # rad (10 deg), ... or its fitted turn exceeds this
    reach: float = 0.04  # m, points this close to a tile (and nearest to it) are its points ...
    height_slack: float = 0.005  # m, ... unless they lie this much above its top or below its bottom
    min_points: int = 40  # fewer points: the tile cannot be judged
    placement_share: float = 0.35  # a tile is not shown in place when under this share of the pixels it should
    placement_judged_share: float = 0.75  # fill are decisive and under this share are judged at all
    min_off_share: float = 0.15  # refit only when this share of its points is off its faces
    improvement: float = 0.85  # the refit must bring the median distance below this share of it before ...
    min_gain: float = 0.0005  # m, ... and by this much: points already on its faces are not put better
    iterations: int = 6
    max_shift: float = 0.06  # m, fits beyond these are not believed ...
    max_turn: float = math.radians(45.0)  # rad, ... (a run-off fit, not a misplaced tile)
    significance: float = 8.0  # a fitted shift must stand this many sigmas clear of zero ...
    turn_significance: float = 7.0  # ... and a fitted turn this many
    turn_resolution: float = 2.0  # a turn moves the tile's corners this many times the motion resolved at its depth
    kept_share: float = 0.1  # a tile that slipped still covers part of its place: this share of its pixels agree
    other_shape_share: float = 0.3  # not its shape: at least this share of its decisive pixels agree, and
    other_shape_pixels: int = 30  # ... this share see through it, of at least this many decisive pixels
    shape_resolution: float = 0.02  # m, ... where the camera resolves this (`depth_noise`; 2.6 m deep)
    sticking_out: float = 0.015  # m off its faces: a point of the tile's own that its planned shape does not explain
    sticking_out_share: float = 0.25  # something else lies there when this share of its points stick out ...
    sticking_out_points: int = 20  # ... and at least this many
    reach_over: float = 0.07  # m beside a tile: a long rectangle swapped for a square reaches 6.5 cm past it
    settled_median: float = 0.004  # m, a refit from "in place" leaving a smaller median distance needs no
    # other start ...
    start_turns: tuple[float, ...] = (math.radians(20.0), math.radians(35.0))  # ... else also from these
    fitted_share: float = 0.7  # a refit the planned pose's pixels cannot confirm stands when this share of
    fitted_gain: float = 0.25  # ... the pixels at the fitted pose agree, this share more than at the planned
    fitted_pixels: int = 30  # ... pose, of at least this many decisive pixels (`pose_hypotheses`)
    disturbed_share: float = 0.08  # refit whatever the first step says when this share of its decisive pixels
    disturbed_pixels: int = 15  # ... and at least this many disagree with its planned pose
    rival_share: float = 0.75  # another type lies there when it explains this share of the pixels where
    rival_pixels: int = 20  # ... the two types differ, and at least this many (`type_hypotheses`)
    look_alike: float = 0.5  # another type whose footprint shares this much of the union with the tile's ...
    rival_doubt_pixels: int = 1  # ... keeps it from being shown in place when it explains as many of the
    # pixels where the two differ as the tile's own type, and at least this many (a square where a
    # triangle was planned: 0 to 7 and 0 to 17)
    hinted_share: float = 0.6  # a first step this share of a flag, unconfirmed: the tile is undetermined
    pin_radius: float = 0.3  # m: the other tiles' points this near a moved tile tell its motion from a misalignment ...
    pin_motion: float = 0.005  # m: ... those the motion would carry this far across their faces ...
    pin_points: int = 30  # ... at least this many of them ...
    pin_share: float = 0.4  # ... fitting worse, brought back by it, by this share of how far it carries them


@dataclass(frozen=True)
class TileFit:
    """What the points say about one tile's placement."""

    points: int
    residual: float  # m, RMS distance of its points to its expected faces
    judged: bool  # enough points to tell
    misplaced: bool
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # x, y (m), yaw (rad) of the tile's motion
    residual_after: float = 0.0  # m, median distance of its points to its faces after the refit
    first_step: Array | None = None  # the linearised estimate (G's x, y, turn) that decided on a refit
    median_before: float = 0.0  # m, median distance of the refitted points to the tile where it should be
    sigmas: tuple[float, float] = (0.0, 0.0)  # significance of the fitted shift and turn
    sticking_out: int = 0  # its points off its faces by more than `sticking_out`, unexplained by a refit
    unresolved: bool = False  # a clear motion fitted, but short of a flag or of what the camera resolves
    resolution: float = 0.0  # m, the smallest motion the camera resolves at the depth of its points


@dataclass(frozen=True)
class ScanPoints:
    """Aligned candidate points (map frame) and what one closest-point query on S_a says of them."""

    points: Array  # (N, 3)
    depth: Array  # (N,) depth in the camera (m)
    nearest_tile: NDArray[np.int64]  # (N,) index of the nearest expected tile
    closest: Array  # (N, 3) closest point on it
    normal: Array  # (N, 3) surface normal there


@dataclass(frozen=True)
class PlacementContext:
    """What the refits need to know besides the points.

    `tiles` (in `patches`' order): a fitted motion that would push a tile into another one that is
    there (`solid`) is not believed, tiles do not interpenetrate. `disturbed`: only tiles whose
    pixels do not all agree with the model are refitted at all; `suspects` (tile indices) are
    refitted even when the first linearised step says little. `surfaces` answers the closest-point
    queries of the refits. `by_robots`: the points inside another robot's box grown by its
    localization error; they prove nothing stands at a tile's place (a Kinect pixel straddling a
    tile's edge and the face of a robot parked 4 cm behind it lands between the two).
    """

    patches: PlanarPatches
    camera_position: Array
    tiles: Sequence[PlacedTile]
    surfaces: TileSurfaces
    solid: Sequence[bool]
    disturbed: Sequence[bool]
    suspects: Sequence[int] = ()
    by_robots: NDArray[np.bool_] | None = None


def confirmed_by_pixels(
    fit: TileFit, agree: int, see_through: int, in_front: int, settings: MisplacementSettings, blank: int = 0
) -> bool:
    """Whether a refit that says "moved" is borne out by the tile's pixels: a tile that moved has left
    some of its expected surface (see-through) and may stand in front of it (in front). A shift
    of 1.5 cm or more shows on a good share of its pixels, a turn of a small tile on a few corners.
    And it still covers part of its place (`agree`): a tile that is gone leaves only the surfaces
    behind it and blanks (`blank`), which a refit can mistake for the tile's faces slipped aside.
    Something in front of it with nothing seen through is no sign that it left its place: a wrong
    tile lying on it shows so (an octagon in the place of the long rectangle on a square made the
    square look turned 33 degrees); that refit stands only if its fitted pose is borne out
    (`pose_hypotheses`)."""
    if not fit.misplaced or see_through == 0:
        return False
    disagree = see_through + in_front
    if agree < max(1.0, settings.kept_share * (agree + disagree + blank)):
        return False
    shifted = math.hypot(fit.offset[0], fit.offset[1]) >= 0.6 * settings.shift
    needed = max(1.0, 0.05 * (agree + disagree)) if shifted else 1.0
    return disagree >= needed


def other_shape(agree: int, against: int, settings: MisplacementSettings, resolution: float = 0.0) -> bool:
    """Whether a tile's place holds something of another shape (a tile of the wrong type; beyond
    the paper, its future work): a good share of its pixels find its surface where expected, and a
    good share see through where the planned tile would be, which no motion of the planned tile
    explains. A tile in place has its pixels agree almost everywhere, a missing one almost nowhere;
    either at the edges of a view can split its pixels, but not both halves at once on this many.
    Not where the camera resolves no less than `shape_resolution` (`resolution`, m): 3.3 m off, the
    pixels of a 5 cm block in place split so at its edges."""
    decisive = agree + against
    if decisive < settings.other_shape_pixels or resolution > settings.shape_resolution:
        return False
    share = settings.other_shape_share * decisive
    return agree >= share and against >= share


def too_little_seen(decisive: int, judged: int, expected: int, settings: MisplacementSettings) -> bool:
    """Whether a tile called present showed too little of itself to say it lies in place: few of
    the pixels it should fill (`expected`) are decisive (`placement_share`) and a good part of them
    are not judged at all (`placement_judged_share`: hidden behind a robot or a box, masked, too
    oblique). What is left of such a tile may be only where its planned and its real outline
    overlap, its edges, which would tell a turn or a shift, hidden: a cap turned 25 degrees, seen
    past a robot on 24 of its 82 pixels (52 judged), was called present. A tile seen whole whose
    pixels are mostly ambiguous (a 4 cm square from 1.9 m: 23 decisive of 70, 64 judged) still is.
    Costs 2-3% of the present verdicts (vi_accuracy, two seeds)."""
    return decisive < settings.placement_share * expected and judged < settings.placement_judged_share * expected


def assess(scan: ScanPoints, context: PlacementContext, settings: MisplacementSettings) -> dict[int, TileFit]:
    """Judge every tile (by index into context.patches.tile_ids) from the aligned candidate points."""
    owners = _owners(scan, context, settings)
    first = _first_steps(scan, owners, context.patches, settings)
    fits: dict[int, TileFit] = {}
    # the most-off tiles first: once one is found moved, the points it explains are its own and
    # cannot make a neighbour look moved too
    claimed = np.zeros(len(scan.points), dtype=bool)
    present = np.flatnonzero(first.points > 0)
    for index in present[np.argsort(-first.rms[present], kind="stable")]:
        fit = _judge_tile(int(index), scan, owners, first, claimed, context, settings)
        fits[int(index)] = fit
    explained = claimed if context.by_robots is None else claimed | context.by_robots
    out = _sticking_out(scan, owners, context.patches, explained, settings)
    return {index: replace(fit, sticking_out=int(out[index])) for index, fit in fits.items()}


def _sticking_out(
    scan: ScanPoints, owners: _Owners, patches: PlanarPatches, explained: NDArray[np.bool_],
    settings: MisplacementSettings,
) -> NDArray[np.int64]:
    """Per tile: its points clear of its faces at its own height (a point above a tile's top is
    something resting on it, not part of it), and those reaching over its neighbours beside it,
    which nothing `explained` (a refit of a tile found moved, or a robot standing there)."""
    owner = owners.owner
    tile = np.minimum(owner, len(patches) - 1)
    z = scan.points[:, 2]
    level = (z >= patches.tile_low[tile, 2] - 0.005) & (z <= patches.tile_high[tile, 2] + 0.005)
    out = (owners.distance > _off_faces(scan, settings)) & level & ~explained
    own = np.bincount(owner[out], minlength=len(patches) + 1)[:-1]
    return own + _reaching_over(scan, patches, explained, settings)


def _reaching_over(
    scan: ScanPoints, patches: PlanarPatches, claimed: NDArray[np.bool_], settings: MisplacementSettings,
) -> NDArray[np.int64]:
    """Per tile: points at its own height within `reach_over` beside it, clear of every expected face and
    standing over the structure (above the top of a tile whose footprint box holds them). No
    expected tile explains them, and only something resting at that tile's place can hold them up
    there: a long rectangle where a 4 cm square was planned reaches over the tops of the square's
    lower neighbours, 2 cm above them (clutter on the floor never stands over the structure). A
    point beside several tiles counts for the smallest of them."""
    count = len(patches)
    gap = scan.points - scan.closest
    clear = (np.einsum("ij,ij->i", gap, gap) > _off_faces(scan, settings) ** 2) & ~claimed
    if count == 0 or not clear.any():
        return np.zeros(count, dtype=np.int64)
    points = scan.points[clear]
    low, high = patches.tile_low[None, :, :], patches.tile_high[None, :, :]
    outside = np.maximum(0.0, np.maximum(low[..., :2] - points[:, None, :2], points[:, None, :2] - high[..., :2]))
    beside = np.hypot(outside[..., 0], outside[..., 1])
    z = points[:, None, 2]
    under = np.where(beside == 0.0, high[..., 2], -np.inf).max(axis=1)  # the structure's top below each point
    # beside the structure is not over it: robots and clutter standing by it reach no tile from above
    over = np.isfinite(under) & (z[:, 0] > under + settings.sticking_out)
    points, beside, z = points[over], beside[over], z[over]
    top = _tops(points)
    points, beside, z = points[top], beside[top], z[top]
    level = (z > low[..., 2] + 0.005) & (z <= high[..., 2] + 0.005)  # the tile's body, not what rests on it
    within = level & (beside <= settings.reach_over)
    # of the tiles beside such a point, the smallest: a tile of the wrong type covers the planned
    # tile's place and more, so it is the small one that was swapped for something bigger
    area = np.prod(patches.tile_high[:, :2] - patches.tile_low[:, :2], axis=1)
    smallest = np.argmin(np.where(within, area[None, :], np.inf), axis=1)
    held = within.any(axis=1)
    return np.bincount(smallest[held], minlength=count)


def _off_faces(scan: ScanPoints, settings: MisplacementSettings) -> Array:
    """Per point: how far (m) off every expected face it must lie to stick out, `sticking_out`, or
    more where the depth noise is larger (3 m off, a disparity step is 2.6 cm)."""
    return np.maximum(settings.sticking_out, resolved_motion(scan.depth))


def _tops(points: Array, radius: float = 0.01, rise: float = 0.01) -> NDArray[np.bool_]:
    """Which of `points` have none of the others within `radius` beside them and `rise` higher: the
    tops of what stands there (the side of a tile resting on the next layer reaches down to a lower
    tile's height, its top does not)."""
    if len(points) > 4000:  # that much unexplained over the structure is no tile: none counts
        return np.zeros(len(points), dtype=bool)
    apart = np.hypot(points[:, None, 0] - points[None, :, 0], points[:, None, 1] - points[None, :, 1])
    higher = points[None, :, 2] > points[:, None, 2] + rise
    return ~np.any((apart <= radius) & higher, axis=1)


def hinted_motion(fit: TileFit, tile: PlacedTile, settings: MisplacementSettings) -> bool:
    """Whether a tile not found moved still has points that lean towards a motion: a first step of
    `hinted_share` of a flag or more, that moves the tile (its corners, for a turn) at least as far as
    the camera resolves at its depth. Such a tile is not shown in place. (Independent scenes: wedges
    turned 25-35 degrees and seen where none of their pixels disagreed stepped 0.66-0.97 of a flag's
    turn and were called present; a 4 cm square in place 1.9 m off stepped 0.77 of a flag's turn,
    its corners 4 mm, where the camera resolves 1.1 cm.)"""
    if not fit.judged or fit.first_step is None:
        return False
    step = fit.first_step
    shift, turn = math.hypot(step[0], step[1]), abs(step[2])
    shifted = shift >= settings.hinted_share * settings.shift and shift >= fit.resolution
    turned = turn >= settings.hinted_share * settings.turn and _corner_reach(tile) * turn >= fit.resolution
    return shifted or turned


def something_else_there(fit: TileFit, settings: MisplacementSettings) -> bool:
    """Whether a tile that no motion of its own explains has something else at its place (a tile of
    the wrong type, bigger than it; beyond the paper, its future work): a good share of the points
    nearest to it stand clear of its faces, where neither it nor any other expected tile is."""
    if fit.misplaced or not fit.judged:
        return False
    return fit.sticking_out >= max(settings.sticking_out_points, settings.sticking_out_share * fit.points)


@dataclass(frozen=True)
class _Owners:
    """Which tile each point belongs to (len(patches): none), and its way to that tile's surface."""

    owner: NDArray[np.int64]
    distance: Array  # (N,) to the nearest expected surface
    order: NDArray[np.int64]  # points sorted by owner ...
    bounds: NDArray[np.int64]  # ... tile k's points are order[bounds[k]:bounds[k + 1]]


def _owners(scan: ScanPoints, context: PlacementContext, settings: MisplacementSettings) -> _Owners:
    gap = scan.points - scan.closest
    distance = np.sqrt(np.einsum("ij,ij->i", gap, gap))
    # a point can only lie on a face the camera sees: one whose nearest face looks away from the
    # camera (the bottom of a removed tile, on the top of the tile below it) belongs to no tile here
    facing = np.einsum("ij,ij->i", scan.normal, context.camera_position - scan.closest) > 0
    own = (distance <= settings.reach) & (facing | (distance > 0.005))
    count = len(context.patches)
    # a tile slips in the plane, it does not rise or sink: a point above its top or below its bottom
    # is another tile's (a triangle that slid on a long rectangle, its top 2 cm above the rectangle's,
    # made the rectangle fit a 17-29 degree turn, and the rectangle was taken off with it)
    own &= _in_height_band(scan.points, scan.nearest_tile, context.patches, settings.height_slack)
    owner = np.where(own, scan.nearest_tile, count)
    order = np.argsort(owner, kind="stable")
    return _Owners(owner, distance, order, np.searchsorted(owner[order], np.arange(count + 1)))


def _in_height_band(points: Array, tiles: NDArray[np.int64], patches: PlanarPatches,
                    slack: float) -> NDArray[np.bool_]:
    """Whether each point lies within `slack` of the heights of its tile (`tiles`: indices)."""
    tile = np.clip(tiles, 0, len(patches) - 1)
    z = points[:, 2]
    return (z >= patches.tile_low[tile, 2] - slack) & (z <= patches.tile_high[tile, 2] + slack)


@dataclass(frozen=True)
class _FirstSteps:
    points: NDArray[np.int64]  # per tile: points it owns
    rms: Array  # per tile: RMS distance of those points to its faces
    step: Array  # (tiles, 3) one linearised step of the planar fit: x, y, turn


def _first_steps(
    scan: ScanPoints, owners: _Owners, patches: PlanarPatches, settings: MisplacementSettings
) -> _FirstSteps:
    """One linearised step of the planar fit for every tile at once: its points' residuals to its
    surface against x, y and a turn about the tile's centre (off-face points use the way to the
    face)."""
    owner, distance, count = owners.owner, owners.distance, len(patches) + 1
    gap = scan.points - scan.closest
    direction = np.where((distance > 0.002)[:, None], gap / np.maximum(distance, 1e-9)[:, None], scan.normal)
    arm = scan.points[:, :2] - patches.tile_centroid[np.minimum(owner, len(patches) - 1), :2]
    rows = np.stack(
        [direction[:, 0], direction[:, 1], arm[:, 0] * direction[:, 1] - arm[:, 1] * direction[:, 0]], 1
    )
    residual = np.einsum("ij,ij->i", gap, direction)
    normal_matrix = np.stack(
        [np.bincount(owner, weights=rows[:, a] * rows[:, b], minlength=count) for a in range(3) for b in range(3)],
        1,
    ).reshape(count, 3, 3)[:-1]
    gradient = np.stack([np.bincount(owner, weights=rows[:, a] * residual, minlength=count) for a in range(3)], 1)[
        :-1
    ]
    points_of = np.bincount(owner, minlength=count)[:-1]
    squared = np.bincount(owner, weights=distance**2, minlength=count)[:-1]
    step = np.zeros((len(patches), 3))
    for index in np.flatnonzero(points_of >= settings.min_points):
        matrix = normal_matrix[index] + np.eye(3) * 1e-6 * max(np.trace(normal_matrix[index]), 1e-9)
        step[index] = -np.linalg.solve(matrix, gradient[index])
    return _FirstSteps(points_of, np.sqrt(squared / np.maximum(points_of, 1)), step)


def _judge_tile(
    index: int,
    scan: ScanPoints,
    owners: _Owners,
    first: _FirstSteps,
    claimed: NDArray[np.bool_],
    context: PlacementContext,
    settings: MisplacementSettings,
) -> TileFit:
    """Refit one tile when its first step, its pixels or an earlier scan hint that it moved; marks
    the points a tile found moved explains as `claimed`."""
    count, rms, step = int(first.points[index]), float(first.rms[index]), first.step[index]
    judged = bool(count >= settings.min_points)
    hint = _step_reaches(step, 0.4, settings)
    # a first step as large as a flag is reason enough where no pixel disagrees: a triangle turned 29
    # degrees, seen at grazing incidence, agreed on all its 82 pixels and was called present
    possible = bool(context.disturbed[index]) or _step_reaches(step, 1.0, settings)
    own = owners.order[owners.bounds[index] : owners.bounds[index + 1]]
    resolution = float(resolved_motion(np.median(scan.depth[own]))) if len(own) else math.inf
    unmoved = TileFit(points=count, residual=rms, judged=judged, misplaced=False, residual_after=rms, first_step=step,
                      resolution=resolution)
    if not (judged and possible and (hint or index in context.suspects)):
        return unmoved
    mine = own[~claimed[own]]
    if len(mine) < settings.min_points:
        return replace(unmoved, judged=False)
    refit = _fit_tile(scan.points, scan.nearest_tile, owners.distance, mine, claimed, index, context, settings)
    offset = refit.offset
    shift, corner_motion = math.hypot(offset[0], offset[1]), _corner_reach(context.tiles[index]) * abs(offset[2])
    shifted = shift >= settings.shift and refit.shift_sigmas >= settings.significance
    turned = abs(offset[2]) >= settings.turn and refit.turn_sigmas >= settings.turn_significance
    # beyond 2.6 m the camera resolves no motion under 2 cm: there a fitted motion within the noise is
    # no motion (an arcade's pier block 3 m off, in place, fitted 1.9 cm), though no proof of none either
    # and a turn must move the corners further: across a 5 cm face 2 m off, disparity steps of 1.1 cm
    # make a staircase that fits as a turn (pier blocks in place fitted turned 15-42 degrees)
    resolved_shift = shifted and shift >= resolution
    resolved_turn = turned and corner_motion >= settings.turn_resolution * resolution
    unresolved = (shifted or turned) and not (resolved_shift or resolved_turn)
    leaning = _leaning(offset, refit, settings)
    shifted, turned = resolved_shift, resolved_turn
    # a fit that ran off (further than a tile slips when placed) explains nothing
    believable = math.hypot(offset[0], offset[1]) <= settings.max_shift and abs(offset[2]) <= settings.max_turn
    if not turned:  # a turn within the noise is no part of the motion (it could push the tile into a neighbour)
        offset = (offset[0], offset[1], 0.0)
    moved = (shifted or turned) and believable and _fits_among(context.tiles, index, offset, context.solid)
    if moved and not _told_from_misalignment(scan, owners, index, refit, claimed, context, settings):
        moved, unresolved = False, True
    # the refit must explain the points better; a clear turn of a small tile barely changes the
    # distances (the noise is as large as the corners' motion), its significance speaks for it
    better = refit.after <= min(settings.improvement * refit.before, refit.before - settings.min_gain) or (
        turned and refit.turn_sigmas >= 1.5 * settings.turn_significance
    )
    if moved and better:
        claimed[refit.explained] = True
    return TileFit(
        points=count,
        residual=rms,
        judged=True,
        misplaced=bool(moved and better),
        offset=offset,
        residual_after=refit.after,
        first_step=step,
        median_before=refit.before,
        sigmas=(refit.shift_sigmas, refit.turn_sigmas),
        # a clear motion short of a flag is no proof of "in place" either: a 4 cm square turned 16
        # degrees, fitted 8.9 (7 sigmas), was called present from eight camera positions
        unresolved=unresolved or (leaning and not (moved and better)),
        resolution=resolution,
    )


def _leaning(offset: tuple[float, float, float], refit: _Refit, settings: MisplacementSettings) -> bool:
    """Whether a refit found a clear motion (as significant as a flag asks) of at least `hinted_share`
    of a flag's size, whether or not it reaches a flag."""
    shift = math.hypot(offset[0], offset[1])
    return (shift >= settings.hinted_share * settings.shift and refit.shift_sigmas >= settings.significance) or (
        abs(offset[2]) >= settings.hinted_share * settings.turn and refit.turn_sigmas >= settings.turn_significance)


def _told_from_misalignment(
    scan: ScanPoints, owners: _Owners, index: int, refit: _Refit, claimed: NDArray[np.bool_],
    context: PlacementContext, settings: MisplacementSettings,
) -> bool:
    """Whether the points of the tiles around a tile found moved pin the scan down against its
    motion. Had the scan been misaligned by that motion instead, bringing every point back by it
    would put the others' points onto their faces as well as its own; a tile moved alone leaves
    them off their faces once brought back. Only points the motion carries across their faces
    (`pin_motion`) can tell, and at least `pin_points` of them must: with too few the tile's motion
    is no evidence. (In CI, a right long rectangle in the middle of the base row, its ends flush
    with its neighbours', took a 1.7 cm misalignment along the row as its own from two views, and was
    taken off the structure with the five tiles above it.)"""
    centre = context.patches.tile_centroid[index]
    near = np.hypot(scan.points[:, 0] - centre[0], scan.points[:, 1] - centre[1]) <= settings.pin_radius
    others = near & (owners.owner != index) & (owners.owner < len(context.patches)) & ~claimed
    others[refit.explained] = False
    if context.by_robots is not None:
        others &= ~context.by_robots
    chosen = np.flatnonzero(others)
    back = _apply(scan.points[chosen], centre, refit.back[0], refit.back[1])
    across = np.abs(np.einsum("ij,ij->i", back - scan.points[chosen], scan.normal[chosen]))
    pinning = across >= settings.pin_motion
    if np.count_nonzero(pinning) < settings.pin_points:
        return False
    chosen, back, across = chosen[pinning], back[pinning], across[pinning]
    # off the plane of the face each point was found on: a point carried into a 2 cm tile is soon as
    # near its top as it was to its side
    normal, face = scan.normal[chosen], scan.closest[chosen]
    before = np.abs(np.einsum("ij,ij->i", scan.points[chosen] - face, normal))
    after = np.abs(np.einsum("ij,ij->i", back - face, normal))
    worse = after - before
    return bool(np.median(worse) >= settings.pin_share * np.median(across))


def _corner_reach(tile: PlacedTile) -> float:
    """How far (m) the farthest corner of a tile's footprint lies from its centre: a turn moves it most."""
    corners = tile.vertices[:, :2] - tile.centroid[:2]
    return float(np.max(np.hypot(corners[:, 0], corners[:, 1])))


def _step_reaches(step: Array, share: float, settings: MisplacementSettings) -> bool:
    """Whether a first step (x, y, yaw) reaches `share` of the shift or of the turn that flags a tile."""
    return math.hypot(step[0], step[1]) >= share * settings.shift or abs(step[2]) >= share * settings.turn


def moved_as_one(
    offsets: Sequence[tuple[float, float, float]], centroids: Sequence[Sequence[float]], settings: MisplacementSettings
) -> bool:
    """Whether the motions found for several tiles look like one motion of them all, which is what a
    misaligned scan makes the tiles look like: the same shift of 1.5 cm or more (turns aside: a
    turned tile's refit takes the common shift too), or one rigid turn of the map. Turned by theta
    about some point and shifted, the map moves a tile whose centroid is c by (R(theta) - I) c + t:
    the turns agree and the shifts, less what that turn swings each centroid by, agree. Tiles that
    slipped when placed each move their own way; two wedges turned by the same 30 degrees 10 cm
    apart did not move as one (one turn would have swung them 5 cm apart). A tile of another type in
    its place has no motion and is part of none. `offsets`: (x, y, yaw) per tile; `centroids`: its
    planned centroid (x, y, ...) in the map."""
    motions = np.asarray(offsets, dtype=float).reshape(-1, 3)
    centres = np.array([c[:2] for c in centroids], dtype=float).reshape(-1, 2)
    moving = np.any(motions != 0.0, axis=1)
    motions, centres = motions[moving], centres[moving]
    if len(motions) < 2:
        return False
    shifts = motions[:, :2]
    if _agree(shifts, settings.shift / 2) and np.linalg.norm(shifts.mean(axis=0)) >= settings.shift:
        return True
    if np.ptp(motions[:, 2]) > settings.turn:
        return False
    turn = float(np.mean(motions[:, 2]))
    cos, sin = math.cos(turn), math.sin(turn)
    swing = centres @ np.array([[cos - 1.0, sin], [-sin, cos - 1.0]])  # (R - I) c, c as rows
    return _agree(shifts - swing, settings.shift / 2)


def _agree(vectors: Array, within: float) -> bool:
    """Whether every one of `vectors` (rows) lies within `within` of their mean."""
    return bool(np.max(np.linalg.norm(vectors - vectors.mean(axis=0), axis=1)) <= within)


def moved_tile(tile: PlacedTile, offset: tuple[float, float, float]) -> PlacedTile:
    """The tile turned by offset[2] about its centroid's vertical and shifted by offset[0:2]."""
    turn = rotation_from_rpy(0.0, 0.0, offset[2])
    centroid = tile.centroid
    position = turn @ (tile.position - centroid) + centroid + np.array([offset[0], offset[1], 0.0])
    return PlacedTile(tile.tile_id, tile.type_name, tile.shape, turn @ tile.rotation, position)


def _fits_among(
    tiles: Sequence[PlacedTile], index: int, offset: tuple[float, float, float], solid: Sequence[bool] | None
) -> bool:
    """Whether the tile, moved by `offset`, stays clear of every other tile that is there (5 mm slack)."""
    moved = moved_tile(tiles[index], offset)
    low, high = moved.aabb
    for k, other in enumerate(tiles):
        if k == index or (solid is not None and not solid[k]):
            continue
        other_low, other_high = other.aabb
        if np.any(other_low > high + 0.01) or np.any(other_high < low - 0.01):
            continue
        if separation(moved, other) < -0.005:
            return False
    return True


@dataclass(frozen=True)
class _Refit:
    offset: tuple[float, float, float]  # the tile's motion: x, y (m), yaw (rad)
    before: float  # m, median distance of the final points to the tile where it should be ...
    after: float  # ... and where the fit puts it
    shift_sigmas: float  # significance (standard deviations) of the fitted shift ...
    turn_sigmas: float  # ... and turn
    explained: NDArray[np.int64]  # the points the moved tile explains
    back: tuple[float, Array] = (0.0, np.zeros(2))  # G: turn (rad) about the tile's centroid, then shift (m),
    # that brings its points back onto the tile where it should be


def _fit_tile(
    points: Array,
    nearest_tile: NDArray[np.int64],
    distance: Array,
    mine: NDArray[np.int64],
    claimed: NDArray[np.bool_],
    index: int,
    context: PlacementContext,
    settings: MisplacementSettings,
) -> _Refit:
    """Refit tile `index` on its points, then once more on the points that the moved tile explains
    better than any other tile does (a moved tile's points may have been closer to a neighbour's
    faces). Points `claimed` by a tile already found moved are left out."""
    patches, camera_position, surfaces = context.patches, context.camera_position, context.surfaces
    centre = patches.tile_centroid[index]
    theta, shift, covariance = _refit_from_turns(points[mine], index, context, settings)
    chosen = mine
    for _ in range(3):  # a tile that moved far takes a few rounds to collect all of its points
        reach = settings.reach + float(np.hypot(*shift))
        low, high = patches.tile_low[index] - reach, patches.tile_high[index] + reach
        # across the plane only: the tile's own height band (see `_owners`)
        low[2] = patches.tile_low[index][2] - settings.height_slack
        high[2] = patches.tile_high[index][2] + settings.height_slack
        around = np.flatnonzero(np.all((points >= low) & (points <= high), axis=1) & ~claimed)
        projection = _project(
            patches,
            surfaces,
            _apply(points[around], centre, theta, shift),
            index,
            settings.reach,
            camera_position,
        )
        keep = projection.found & ((nearest_tile[around] == index) | (projection.distance < distance[around]))
        if keep.sum() < settings.min_points or np.array_equal(around[keep], chosen):
            break
        chosen = around[keep]
        previous = (theta, shift.copy())
        theta, shift, _, covariance = _refit(
            points[chosen], index, patches, camera_position, settings, surfaces, (theta, shift)
        )
        if abs(theta - previous[0]) < 0.005 and np.linalg.norm(shift - previous[1]) < 0.001:
            break
    return _summarise(points, chosen, index, theta, shift, covariance, context)


def _refit_from_turns(points: Array, index: int, context: PlacementContext,
                      settings: MisplacementSettings) -> tuple[float, Array, Array]:
    """`_refit` from "in place", and when that leaves the points off the tile (a turn of 30 degrees
    is far outside the linearisation) also from turns of either sign up to half the tile's symmetry
    turn: the believable fit with the smallest median distance of all the points to the tile
    (points it leaves beyond reach count as far: a fit must not win by dropping points)."""
    patches, camera_position, surfaces = context.patches, context.camera_position, context.surfaces
    theta, shift, _, covariance = _refit(points, index, patches, camera_position, settings, surfaces)
    best = (_median_distance(points, index, theta, shift, context), theta, shift, covariance)
    if best[0] <= settings.settled_median and _believable(theta, shift, settings):
        return theta, shift, covariance
    if not _believable(theta, shift, settings):
        best = (math.inf, *best[1:])
    half_symmetry = math.pi / patches.tile_symmetry[index]
    for turn in settings.start_turns:
        if turn > min(half_symmetry, settings.max_turn):
            continue
        for start in (turn, -turn):
            theta, shift, _, covariance = _refit(
                points, index, patches, camera_position, settings, surfaces, (start, np.zeros(2)))
            median = _median_distance(points, index, theta, shift, context)
            if _believable(theta, shift, settings) and median < best[0]:
                best = (median, theta, shift, covariance)
    if math.isinf(best[0]):
        return theta, shift, covariance  # nothing believable: the caller finds the fit ran off
    return best[1], best[2], best[3]


def _median_distance(points: Array, index: int, theta: float, shift: Array, context: PlacementContext) -> float:
    moved = _apply(points, context.patches.tile_centroid[index], theta, shift)
    projection = _project(context.patches, context.surfaces, moved, index, 0.08, context.camera_position)
    return float(np.median(np.where(projection.found, projection.distance, 0.08)))


def _believable(theta: float, shift: Array, settings: MisplacementSettings) -> bool:
    """A motion of G within what a tile slips when placed (not a fit that ran off)."""
    return float(np.hypot(*shift)) <= settings.max_shift + 0.05 and abs(theta) <= settings.max_turn + 0.1


def _summarise(
    points: Array,
    chosen: NDArray[np.int64],
    index: int,
    theta: float,
    shift: Array,
    covariance: Array,
    context: PlacementContext,
) -> _Refit:
    """How well the points fit the tile where it should be and where the fit puts it (median
    distances, robust to the odd point of a neighbour), and how many standard deviations the fitted
    shift and turn are away from "in place"."""
    patches, camera_position, surfaces = context.patches, context.camera_position, context.surfaces
    centre = patches.tile_centroid[index]
    unmoved = _project(patches, surfaces, points[chosen], index, 0.08, camera_position)
    try:
        shift_sigmas = float(np.sqrt(shift @ np.linalg.solve(covariance[:2, :2], shift)))
    except np.linalg.LinAlgError:
        shift_sigmas = 0.0
    # a square turned by 84 degrees is one turned by -6: count turns modulo the tile's symmetry
    step = 2 * math.pi / patches.tile_symmetry[index]
    turn = theta - round(theta / step) * step
    turn_sigmas = abs(turn) / math.sqrt(max(covariance[2, 2], 1e-12))
    final = _project(
        patches, surfaces, _apply(points[chosen], centre, theta, shift), index, 0.08, camera_position
    )
    before = float(np.median(np.where(unmoved.found, unmoved.distance, 0.08)))
    after = float(np.median(np.where(final.found, final.distance, 0.08)))
    explained = chosen[final.found & (final.distance <= 0.006)]
    x, y, _ = _motion(centre, theta, shift)
    return _Refit((x, y, -turn), before, after, shift_sigmas, turn_sigmas, explained, (theta, shift))


class TileSurfaces(Protocol):
    """Closest points on one tile's surface: (closest points, normals there) for (N, 3) points."""

    def closest_on_tile(
        self, points: Array, index: int, camera_position: Array | None = None
    ) -> tuple[Array, Array]: ...


def _project(
    patches: PlanarPatches,
    surfaces: TileSurfaces | None,
    points: Array,
    index: int,
    reach: float,
    camera_position: Array,
) -> Projection:
    """Closest points on tile `index` (within `reach`), by `surfaces` or the patch hierarchy."""
    if surfaces is None:
        return patches.project(points, reach, camera_position, only_tile=index)
    closest, normal = surfaces.closest_on_tile(points, index, camera_position)  # faces it can see
    distance = np.sqrt(np.einsum("ij,ij->i", points - closest, points - closest))
    found = distance <= reach
    return Projection(
        closest, normal, np.where(found, index, -1), np.where(found, 0, -1), np.where(found, distance, np.inf)
    )


def _apply(points: Array, centre: Array, theta: float, shift: Array) -> Array:
    """G(p) = R(theta) (p - centre) + centre + shift, in the horizontal plane."""
    c, s = math.cos(theta), math.sin(theta)
    relative = points[:, :2] - centre[:2]
    moved = points.copy()
    moved[:, 0] = c * relative[:, 0] - s * relative[:, 1] + centre[0] + shift[0]
    moved[:, 1] = s * relative[:, 0] + c * relative[:, 1] + centre[1] + shift[1]
    return moved


def _refit(
    points: Array,
    index: int,
    patches: PlanarPatches,
    camera_position: Array,
    settings: MisplacementSettings,
    surfaces: TileSurfaces | None,
    start: tuple[float, Array] = (0.0, np.zeros(2)),
) -> tuple[float, Array, float, Array]:
    """The planar motion G (turn theta about the tile's centre, then shift) taking `points` onto
    the expected faces of tile `index`, by robust Gauss-Newton; returns theta, shift and the RMS
    distance left. Residuals are taken along the face normal on a face and along the way to the
    face off it, so that points in the middle of a top face neither pull nor hold the fit. Also
    returns the covariance of (shift x, shift y, theta) from the last linearisation: a direction the
    visible faces do not constrain has a large variance."""
    centre = patches.tile_centroid[index]
    theta, shift = start[0], start[1].copy()
    rms = math.inf
    covariance = np.eye(3)
    for _ in range(settings.iterations):
        moved = _apply(points, centre, theta, shift)
        projection = _project(patches, surfaces, moved, index, 0.08, camera_position)
        found = projection.found
        if found.sum() < 6:
            break
        gap = (moved - projection.closest)[found]
        distance = projection.distance[found]
        rms = float(np.sqrt(np.mean(distance**2)))
        off = distance > 0.002
        direction = np.where(
            off[:, None], gap / np.maximum(distance, 1e-9)[:, None], projection.normal[found]
        )
        arm = moved[found, :2] - centre[:2] - shift
        rows = np.stack(
            [direction[:, 0], direction[:, 1], arm[:, 0] * direction[:, 1] - arm[:, 1] * direction[:, 0]], 1
        )
        residual = np.einsum("ij,ij->i", gap, direction)
        weight = np.minimum(1.0, 0.005 / np.maximum(np.abs(residual), 1e-9))
        matrix = (rows * weight[:, None]).T @ rows + np.eye(3) * 1e-6 * max(
            float(np.trace(rows.T @ rows)), 1e-9
        )
        variance = float(np.sum(weight * residual**2) / max(1.0, float(np.sum(weight)) - 3.0))
        covariance = np.linalg.inv(matrix) * max(variance, 1e-6)
        step = -covariance @ ((rows * weight[:, None]).T @ residual) / max(variance, 1e-6)
        shift = shift + step[:2]
        theta += float(step[2])
        if np.linalg.norm(step[:2]) < 1e-4 and abs(step[2]) < 1e-4:
            break
    return theta, shift, rms, covariance


def _motion(centre: Array, theta: float, shift: Array) -> tuple[float, float, float]:
    """The tile's own motion (x, y of its centre, yaw) from G: the inverse of G."""
    c, s = math.cos(-theta), math.sin(-theta)
    back = np.array([c * -shift[0] - s * -shift[1], s * -shift[0] + c * -shift[1]])
    return float(back[0]), float(back[1]), float(-theta)
