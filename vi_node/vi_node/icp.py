"""Point-to-plane ICP of the candidates C_1 against S_a (paper section 2.2.1, last step).

"We perform a 6D (3 location parameters, 3 directional parameters) point to plane ICP, with the
goal to align C_p to S_a ... C_2 is iteratively generated as the projection points of C_1 onto the
virtual structure S_a ... We limit our ICP to a maximum of 10 iterations. ICP results in T_ICP,
an accumulated rotation and translation to align C_1 to S_a ... We set P_v = T_ICP P_p."

Each iteration asks a correspondence function (the patch hierarchy, or Open3D's closest-point
BVH) for the projections, drops pairs farther apart than a shrinking distance, weighs the rest
with a Huber kernel (clutter and misplaced tiles should not pull the pose) and solves the
linearised 6x6 normal equations. The correction is a rigid transform of the map frame:
corrected camera pose = T_ICP @ pose.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import rotation_from_rpy

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Correspondences:
    """Projections of points onto S_a: closest point, its normal, distance (inf: none)."""

    closest: Array
    normal: Array
    distance: Array


# points, max distance -> their projections onto S_a
CorrespondenceFunction = Callable[[Array, float], Correspondences]


@dataclass(frozen=True)
class IcpSettings:
    max_iterations: int = 10  # the paper's limit
    max_distance: float = 0.03  # m, pairs farther apart are ignored in the first iteration ...
    min_distance: float = 0.01  # m, ... shrinking to this
    shrink: float = 0.6  # cut-off factor per iteration
    huber: float = 0.004  # m, residuals beyond this get less weight
    converged_translation: float = 2e-4  # m, an update smaller than this ...
    converged_rotation: float = 4e-4  # rad, ... and this ends the iterations
    degenerate: float = 0.5  # directions the points constrain less than half a point would do not move


@dataclass(frozen=True)
class IcpResult:
    correction: Array  # 4x4 rigid transform of the map frame: aligned = correction @ original
    iterations: int
    rms: float  # m, point-to-plane RMS of the inliers at the last iteration
    inliers: int
    converged: bool


def _rotation_about(omega: Array) -> Array:
    angle = float(np.linalg.norm(omega))
    if angle < 1e-12:
        return np.eye(3)
    axis = omega / angle
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + math.sin(angle) * k + (1 - math.cos(angle)) * (k @ k)


def point_to_plane_icp(
    points: Array, correspond: CorrespondenceFunction, settings: IcpSettings | None = None
) -> IcpResult:
    """Align `points` (N, 3, map frame) to S_a; returns the accumulated correction."""
    settings = settings or IcpSettings()
    total = np.eye(4)
    current = points.astype(np.float64, copy=True)
    rms, inliers, converged = math.inf, 0, False
    iterations = 0
    for k in range(settings.max_iterations):
        iterations = k + 1
        cut = max(settings.min_distance, settings.max_distance * settings.shrink**k)
        pairs = correspond(current, cut)
        use = pairs.distance <= cut
        inliers = int(use.sum())
        if inliers < 6:
            break
        p, q, n = current[use], pairs.closest[use], pairs.normal[use]
        centre = p.mean(axis=0)
        residual = np.einsum("ij,ij->i", p - q, n)
        jacobian = np.hstack([np.cross(p - centre, n), n])
        weight = np.minimum(1.0, settings.huber / np.maximum(np.abs(residual), 1e-12))
        # rotations in units of the points' spread, so that a turn and a shift that move the points
        # as far weigh the same when telling constrained directions from free ones
        spread = float(np.sqrt(np.mean(np.einsum("ij,ij->i", p - centre, p - centre)))) or 1.0
        scale = np.array([spread, spread, spread, 1.0, 1.0, 1.0])
        scaled = jacobian / scale
        hessian = (scaled * weight[:, None]).T @ scaled
        gradient = (scaled * weight[:, None]).T @ residual
        step = -_constrained_solve(hessian, gradient, settings.degenerate) / scale
        rms = float(np.sqrt(np.mean(residual**2)))
        rotation = _rotation_about(step[:3])
        update = np.eye(4)
        update[:3, :3] = rotation
        update[:3, 3] = centre - rotation @ centre + step[3:]
        current = current @ rotation.T + update[:3, 3]
        total = update @ total
        if (
            np.linalg.norm(step[3:]) < settings.converged_translation
            and np.linalg.norm(step[:3]) < settings.converged_rotation
        ):
            converged = True
            break
    return IcpResult(total, iterations, rms, inliers, converged)


def _constrained_solve(hessian: Array, gradient: Array, degenerate: float) -> Array:
    """Solve hessian @ x = gradient along the directions the points constrain only (eigenvalues
    above `degenerate`: one point's normal along a direction adds at most 1): where the visible
    faces leave the pose free (a view of parallel faces lets it slide along them), a few stray
    points would drag it without bound; there it stays where the coarse search put it."""
    values, vectors = np.linalg.eigh(hessian)
    keep = values > max(degenerate, 1e-9 * float(values[-1]))
    return vectors[:, keep] @ ((vectors[:, keep].T @ gradient) / values[keep])


def yaw_shift_transform(yaw: float, pivot: Array, shift: Array) -> Array:
    """4x4 map transform: rotate by `yaw` about the vertical through `pivot`, then shift (x, y)."""
    transform = np.eye(4)
    rotation = rotation_from_rpy(0.0, 0.0, yaw)
    transform[:3, :3] = rotation
    transform[:3, 3] = pivot - rotation @ pivot + np.array([shift[0], shift[1], 0.0])
    return transform
