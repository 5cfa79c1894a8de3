"""Finding a tile of known footprint in a laser scan (paper section 3.1: "The LRF was used by the
assembly robots to detect, pick, and place the tiles").

The laser's plane cuts the tile's side faces, so a tile appears as the part of its footprint's
outline that faces the laser. The method:

1. **Segment** the scan: consecutive valid ranges whose points lie close together (a gap threshold
   that grows with the range and the angular step) form one cluster.
2. **Select** clusters that could be the tile: enough points, an extent no larger than the
   footprint's diameter (plus a margin), optionally within a region of interest (the parts cache).
3. **Fit** the footprint to each cluster: minimise (robust least squares) the distance of every
   point to the nearest edge of the posed footprint that faces the laser, from several yaw starts
   over the footprint's rotational symmetry period.
4. **Check** the fit against the whole scan: the outline's visible edges must be covered by points
   (coverage), and the laser must not have seen *through* the posed footprint (measured ranges far
   behind its visible edges). The best fit that passes gives the tile's pose (x, y, yaw of the tile
   frame in the laser frame) and a quality in [0, 1].

The yaw is reported modulo the footprint's rotational symmetry (e.g. pi for a rectangle), in
[-pi/k, pi/k) for a k-fold symmetric footprint.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares

from hardware_drivers.laser_scan import LaserScanData
from hardware_drivers.planar_pose import Pose2D, wrap_angle
from tiling_assembly import polygons
from tiling_assembly.geometry import PlacedTile
from tiling_assembly.structure import TileType

Array = NDArray[np.float64]


@dataclass(frozen=True)
class LocalizationParams:
    max_range: float = 1.5  # m, points further away are ignored
    cluster_gap: float = 0.02  # m, plus 3 angular steps at the point's range
    max_missing_beams: int = 3  # invalid beams tolerated inside a cluster
    min_points: int = 6
    size_margin: float = 0.03  # m, cluster extent allowed beyond the footprint's diameter
    max_rms: float = 0.008  # m, a worse fit is not this tile
    min_coverage: float = 0.6  # fraction of the visible outline that must carry points
    max_see_through: float = 0.1  # fraction of the visible outline the laser may see through
    see_through_margin: float = 0.03  # m behind the outline that counts as seeing through
    yaw_starts: int = 4  # evenly spread starting yaws per symmetry period (besides edge-aligned ones)
    outline_sample: float = 0.004  # m between checked points of the outline


DEFAULT_PARAMS = LocalizationParams()


@dataclass(frozen=True)
class TileDetection:
    pose: Pose2D  # the tile frame in the laser frame
    rms: float  # m, RMS distance of the cluster's points to the fitted outline
    points: int  # points in the cluster
    coverage: float  # 0..1
    see_through: float  # 0..1
    quality: float  # 0..1

    def __str__(self) -> str:
        return (f"tile at {self.pose} (rms {self.rms * 1000:.1f} mm, {self.points} points, "
                f"coverage {self.coverage:.2f}, quality {self.quality:.2f})")


def footprint_of(tile_type: TileType) -> Array:
    """The tile type's outline on the floor, counter-clockwise, in the tile frame."""
    placed = PlacedTile(0, tile_type.name, tile_type.shape, np.eye(3), np.zeros(3))
    return np.asarray(placed.footprint, dtype=float)


def rotational_symmetry(polygon: Array, tolerance: float = 2e-4) -> int:
    """The largest k (<= 12) such that turning the outline by 2 pi / k about the tile origin maps
    its corners onto themselves."""
    for k in range(12, 1, -1):
        angle = 2.0 * math.pi / k
        turned = Pose2D(0.0, 0.0, angle).transform_points(polygon)
        distances = np.linalg.norm(turned[:, None, :] - polygon[None, :, :], axis=2)
        if np.all(distances.min(axis=1) < tolerance):
            return k
    return 1


def segment_scan(scan: LaserScanData, params: LocalizationParams) -> list[NDArray[np.int64]]:
    """Indices (into scan.ranges) of each cluster of nearby valid points, in angle order; clusters
    whose nearest point is beyond ``max_range`` are left out (after segmenting, so that a surface
    crossing that range is not cut into a tile-sized piece)."""
    indices = np.flatnonzero(scan.valid())
    if len(indices) == 0:
        return []
    r = scan.ranges[indices]
    a = scan.angles[indices]
    xy = np.column_stack([r * np.cos(a), r * np.sin(a)])
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    threshold = params.cluster_gap + 3.0 * abs(scan.angle_increment) * np.minimum(r[:-1], r[1:])
    breaks = (step > threshold) | (np.diff(indices) > params.max_missing_beams + 1)
    clusters = np.split(indices, np.flatnonzero(breaks) + 1)
    return [c for c in clusters if len(c) and scan.ranges[c].min() <= params.max_range]


def _outline(polygon: Array, pose: Pose2D) -> tuple[Array, Array, Array]:
    """Corners a, b of each edge and its outward normal, posed."""
    corners = pose.transform_points(polygon)
    a, b = corners, np.roll(corners, -1, axis=0)
    edge = b - a
    normal = np.column_stack([edge[:, 1], -edge[:, 0]]) / np.linalg.norm(edge, axis=1)[:, None]
    return a, b, normal


def _facing(a: Array, b: Array, normal: Array) -> NDArray[np.bool_]:
    """Edges whose outer side faces the laser at the origin."""
    middle = (a + b) / 2.0
    return np.einsum("ij,ij->i", normal, -middle) > 0.0


def _nearest_on_segments(points: Array, a: Array, b: Array) -> tuple[Array, Array]:
    """For each point, its distance to the nearest segment and the nearest point on it."""
    ab = b - a
    length2 = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-18)
    t = np.clip(np.einsum("kij,ij->ki", points[:, None, :] - a[None], ab) / length2, 0.0, 1.0)
    nearest = a[None] + t[..., None] * ab[None]  # (K, E, 2)
    distances = np.linalg.norm(points[:, None, :] - nearest, axis=2)
    best = distances.argmin(axis=1)
    rows = np.arange(len(points))
    return distances[rows, best], nearest[rows, best]


def _facing_outline(parameters: Array, polygon: Array) -> tuple[Array, Array]:
    a, b, normal = _outline(polygon, Pose2D(*parameters))
    facing = _facing(a, b, normal)
    if not facing.any():
        facing = np.ones(len(a), dtype=bool)
    return a[facing], b[facing]


def _residuals(parameters: Array, points: Array, polygon: Array) -> Array:
    """Distance of every point to the nearest outline edge that faces the laser."""
    return _nearest_on_segments(points, *_facing_outline(parameters, polygon))[0]


def _jacobian(parameters: Array, points: Array, polygon: Array) -> Array:
    """d(residual)/d(x, y, yaw): the nearest point q moves with the pose, so for d = |p - q| and
    u = (p - q) / d: dd/dt = -u and dd/dyaw = -u . perp(q - t)."""
    distances, nearest = _nearest_on_segments(points, *_facing_outline(parameters, polygon))
    u = (points - nearest) / np.maximum(distances, 1e-9)[:, None]
    arm = nearest - parameters[:2]
    d_yaw = -(u[:, 0] * -arm[:, 1] + u[:, 1] * arm[:, 0])
    return np.column_stack([-u[:, 0], -u[:, 1], d_yaw])


def _visible_outline(polygon: Array, pose: Pose2D, spacing: float, grazing_limit: float) -> Array:
    """Sample points of the posed outline that the laser at the origin can see."""
    a, b, normal = _outline(polygon, pose)
    samples = []
    middle = (a + b) / 2.0
    incidence = np.einsum("ij,ij->i", normal, -middle) / np.linalg.norm(middle, axis=1)
    # faces seen at grazing incidence return few, unreliable points: skip them
    seen = _facing(a, b, normal) & (incidence > math.cos(grazing_limit))
    for start, end in zip(a[seen], b[seen], strict=True):
        count = max(2, int(np.linalg.norm(end - start) / spacing))
        t = (np.arange(count) + 0.5) / count
        samples.append(start + t[:, None] * (end - start))
    if not samples:
        return np.zeros((0, 2))
    points = np.vstack(samples)
    # drop samples hidden behind another part of the outline (non-convex footprints)
    bearing = np.arctan2(points[:, 1], points[:, 0])
    distance = np.linalg.norm(points, axis=1)
    keep = np.ones(len(points), dtype=bool)
    for start, end in zip(a, b, strict=True):
        hit = _ray_hits(bearing, start, end)
        keep &= ~(hit < distance - 1e-4)
    return points[keep]


def _ray_hits(bearing: Array, start: Array, end: Array) -> Array:
    d = np.column_stack([np.cos(bearing), np.sin(bearing)])
    e = end - start
    denominator = d[:, 0] * e[1] - d[:, 1] * e[0]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (start[0] * e[1] - start[1] * e[0]) / denominator
        u = (start[0] * d[:, 1] - start[1] * d[:, 0]) / denominator
    hit = (np.abs(denominator) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1)
    return np.where(hit, t, np.inf)


def _check_against_scan(scan: LaserScanData, polygon: Array, pose: Pose2D, params: LocalizationParams,
                        grazing_limit: float) -> tuple[float, float]:
    """(coverage, see-through) of the posed footprint's visible outline in the scan, leaving out
    faces seen beyond `grazing_limit` (rad) from their normal."""
    samples = _visible_outline(polygon, pose, params.outline_sample, grazing_limit)
    if len(samples) == 0:
        return 0.0, 1.0
    bearing = np.arctan2(samples[:, 1], samples[:, 0])
    expected = np.linalg.norm(samples, axis=1)
    # the silhouette's edges fall between beams: leave out the outermost beam on each side
    margin = 1.5 * abs(scan.angle_increment)
    inner = (bearing > bearing.min() + margin) & (bearing < bearing.max() - margin)
    if inner.sum() >= 3:
        samples, bearing, expected = samples[inner], bearing[inner], expected[inner]
    index = np.round((bearing - scan.angle_min) / scan.angle_increment).astype(int)
    inside = (index >= 0) & (index < len(scan.ranges))
    if not inside.any():
        return 0.0, 1.0
    measured = np.full(len(samples), np.nan)
    measured[inside] = scan.ranges[index[inside]]
    finite = np.isfinite(measured)
    on_outline = max(params.see_through_margin / 2.0, 3 * params.max_rms)
    covered = finite & (np.abs(measured - expected) <= on_outline)
    behind = ~finite | (measured > expected + params.see_through_margin)
    occluded = finite & (measured < expected - params.see_through_margin)
    observable = inside & ~occluded
    if not observable.any():
        return 0.0, 1.0
    return float(covered[observable].mean()), float(behind[observable & inside].mean())


def _yaw_starts(points: Array, polygon: Array, period: float, uniform: int) -> list[float]:
    """Starting yaws: each outline edge laid along the straight runs of the points (the whole
    cluster and each half: one or two visible faces), and a few evenly spread ones."""
    directions = []
    half = len(points) // 2
    for part in (points, points[: half + 1], points[half:]):
        if len(part) >= 3:
            _, _, vt = np.linalg.svd(part - part.mean(axis=0))
            directions.append(math.atan2(vt[0, 1], vt[0, 0]))
    edges = np.roll(polygon, -1, axis=0) - polygon
    edge_angles = np.arctan2(edges[:, 1], edges[:, 0])
    candidates = [line - edge + turn
                  for line in directions for edge in edge_angles for turn in (0.0, math.pi)]
    candidates += [-period / 2.0 + period * (i + 0.5) / uniform for i in range(uniform)]
    starts: list[float] = []
    for yaw in candidates:
        yaw = (wrap_angle(yaw) + period / 2.0) % period - period / 2.0
        if all(abs(wrap_angle(yaw - other)) > math.radians(2.0) for other in starts):
            starts.append(yaw)
    return starts


def _refine(points: Array, polygon: Array, start: Pose2D, symmetry: int) -> tuple[Pose2D, float]:
    """Robust least squares of the point-to-facing-outline distances from `start`; the pose (yaw
    modulo the symmetry, in [-period/2, period/2)) and the RMS distance."""
    result = least_squares(
        _residuals, np.array([start.x, start.y, start.yaw]), jac=_jacobian, args=(points, polygon),
        loss="soft_l1", f_scale=0.005, x_scale=np.array([0.01, 0.01, 0.1]), max_nfev=200,
    )
    rms = float(np.sqrt(np.mean(_residuals(result.x, points, polygon) ** 2)))
    period = 2.0 * math.pi / symmetry
    x, y, yaw = result.x
    yaw = (wrap_angle(yaw) + period / 2.0) % period - period / 2.0
    return Pose2D(float(x), float(y), float(yaw)), rms


def fit_footprint(points: Array, polygon: Array, params: LocalizationParams = DEFAULT_PARAMS,
                  symmetry: int | None = None) -> list[tuple[Pose2D, float]]:
    """Local optima of the footprint's pose for one cluster of points (laser at the origin), with
    their RMS point-to-outline distance, best first; one per distinct yaw start."""
    if len(points) < 3:
        return []
    k = symmetry or rotational_symmetry(polygon)
    period = 2.0 * math.pi / k
    centre = np.asarray(polygons.convex_hull_2d(polygon), dtype=float).mean(axis=0)
    mean = points.mean(axis=0)
    away = mean / max(np.linalg.norm(mean), 1e-9)
    fits: list[tuple[Pose2D, float]] = []
    for yaw in _yaw_starts(points, polygon, period, params.yaw_starts):
        turned = Pose2D(0.0, 0.0, yaw).transform_points(polygon - centre)
        # start with the outline's side nearest the laser through the points' mean
        depth = float(np.max(turned @ -away))
        turned_centre = Pose2D(0.0, 0.0, yaw).transform_points(centre[None, :])[0]
        origin = mean + away * depth - turned_centre
        pose, rms = _refine(points, polygon, Pose2D(float(origin[0]), float(origin[1]), yaw), k)
        duplicate = any(
            p.distance_to(pose) < 0.002 and abs(wrap_angle((p.yaw - pose.yaw) * k)) / k < math.radians(1.0)
            for p, _ in fits
        )
        if not duplicate:
            fits.append((pose, rms))
    return sorted(fits, key=lambda f: f[1])


def _candidate_fits(scan: LaserScanData, polygon: Array, params: LocalizationParams,
                    region: tuple[float, float, float] | None) -> list[TileDetection]:
    diameter = float(np.max(np.linalg.norm(polygon[:, None] - polygon[None], axis=2)))
    symmetry = rotational_symmetry(polygon)
    ranges, angles = scan.ranges, scan.angles
    detections = []
    for cluster in segment_scan(scan, params):
        if len(cluster) < params.min_points:
            continue
        r, a = ranges[cluster], angles[cluster]
        points = np.column_stack([r * np.cos(a), r * np.sin(a)])
        extent = np.linalg.norm(points[-1] - points[0])
        if extent > diameter + params.size_margin:
            continue
        if region is not None:
            centre = points.mean(axis=0)
            if math.hypot(centre[0] - region[0], centre[1] - region[1]) > region[2]:
                continue
        fits = fit_footprint(points, polygon, params, symmetry)
        scored = [_score(scan, polygon, params, pose, rms, len(cluster))
                  for pose, rms in fits if rms <= 2.0 * params.max_rms]
        if not scored:
            continue
        # a face seen end-on pins the yaw down poorly: look around the best fit, rank by how well
        # every face that would be visible agrees with the scan (grazing ones included)
        best = max(scored, key=lambda d: d[1])[0]
        for turn in (-8.0, -4.0, 4.0, 8.0):
            start = Pose2D(best.pose.x, best.pose.y, best.pose.yaw + math.radians(turn))
            pose, rms = _refine(points, polygon, start, symmetry)
            if rms <= 2.0 * params.max_rms:
                scored.append(_score(scan, polygon, params, pose, rms, len(cluster)))
        detections.append(max(scored, key=lambda d: d[1])[0])
    return detections


def _score(scan: LaserScanData, polygon: Array, params: LocalizationParams, pose: Pose2D, rms: float,
           points: int) -> tuple[TileDetection, float]:
    """The detection (judged on the faces seen within 75 degrees of their normal) and its ranking
    score (judged on every face seen within 88 degrees)."""
    coverage, see_through = _check_against_scan(scan, polygon, pose, params, math.radians(75.0))
    quality = coverage * (1.0 - see_through) * math.exp(-rms / params.max_rms)
    strict_coverage, strict_see_through = _check_against_scan(scan, polygon, pose, params, math.radians(88.0))
    rank = strict_coverage * (1.0 - strict_see_through) * math.exp(-rms / params.max_rms)
    return TileDetection(pose, rms, points, coverage, see_through, quality), rank


def find_tile(scan: LaserScanData, polygon: Array, params: LocalizationParams = DEFAULT_PARAMS,
              region: tuple[float, float, float] | None = None) -> TileDetection | None:
    """The best-fitting tile of outline `polygon` in the scan, or None when no cluster fits.

    `region`: (x, y, radius) in the laser frame; only clusters centred inside are considered.
    """
    accepted = [
        d for d in _candidate_fits(scan, polygon, params, region)
        if d.rms <= params.max_rms and d.coverage >= params.min_coverage
        and d.see_through <= params.max_see_through
    ]
    return max(accepted, key=lambda d: d.quality, default=None)


def explain_no_tile(scan: LaserScanData, polygon: Array, params: LocalizationParams = DEFAULT_PARAMS,
                    region: tuple[float, float, float] | None = None) -> str:
    """One line saying why find_tile found nothing (for the failure message)."""
    candidates = _candidate_fits(scan, polygon, params, region)
    if not candidates:
        clusters = segment_scan(scan, params)
        where = f" within {region[2]:.2f} m of ({region[0]:.2f}, {region[1]:.2f})" if region else ""
        return f"no cluster of tile size{where} among {len(clusters)} clusters in range"
    best = max(candidates, key=lambda d: d.quality)
    return (f"best candidate rejected: rms {best.rms * 1000:.1f} mm (max {params.max_rms * 1000:.0f}), "
            f"coverage {best.coverage:.2f} (min {params.min_coverage}), "
            f"seen through {best.see_through:.2f} (max {params.max_see_through})")
