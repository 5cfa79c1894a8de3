"""The next viewpoint of the VI robot (paper section 2.2: "a prioritized exploration algorithm,
which aims to map and update the dynamically changing physical structure with priority on
currently targeted building regions").

For every candidate base pose, a virtual scan of S_a is ray traced from where the camera would be
(mount on a level base) at reduced resolution; a tile counts as resolvable from there when the
virtual scan predicts enough judgeable pixels for it (the same test the default mode applies to a
real scan). Other robots (`robot_mask.RobotBoxes`, from the overhead cameras) hide what lies
behind them, and the VI robot cannot stand where they stand. A candidate scores the weights of the
tiles it would resolve: unresolved tiles weigh 1, priority tiles (being built now) more; the best
candidate is returned, ties going to the nearest one.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from vi_node.camera_model import PinholeCamera
from vi_node.evidence import EvidenceSettings, interior
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior
from vi_node.raycast import VirtualScene
from vi_node.robot_mask import RobotBoxes


@dataclass(frozen=True)
class ViewpointScore:
    pose: OverheadPose
    score: float
    resolves: tuple[int, ...]  # tile ids predicted to be resolved from there


def rank_viewpoints(
    scene: VirtualScene,
    low: np.ndarray,
    high: np.ndarray,
    camera: PinholeCamera,
    mount: CameraMount,
    candidates: Sequence[OverheadPose],
    wanted: Mapping[int, float],
    settings: EvidenceSettings | None = None,
    stride: int = 4,
    min_range: float = 0.5,
    max_range: float = 4.5,
    robots: RobotBoxes | None = None,
    clearance: float = 0.35,
) -> list[ViewpointScore]:
    """Score every candidate pose by the weights of the `wanted` tiles (id -> weight) it would
    resolve, seen past the `robots`; a candidate within `clearance` (m) of a robot scores
    nothing. Best first."""
    settings = settings or EvidenceSettings()
    coarse = PinholeCamera(
        camera.fx / stride,
        camera.fy / stride,
        (camera.cx + 0.5) / stride - 0.5,
        (camera.cy + 0.5) / stride - 0.5,
        max(1, camera.width // stride),
        max(1, camera.height // stride),
    )
    cos_limit = math.cos(settings.max_incidence)
    index_of = {int(t): k for k, t in enumerate(scene.tile_ids)}
    scores: list[ViewpointScore] = []
    for pose in candidates:
        if robots is not None and robots.blocks(pose.x, pose.y, clearance):
            scores.append(ViewpointScore(pose, 0.0, ()))
            continue
        optical = camera_prior(pose, mount)
        rows, cols = coarse.box_roi(optical, low, high)
        virtual = scene.cast(coarse, optical, rows, cols, min_range, max_range)
        judged = interior(virtual.tile, virtual.depth) & (virtual.cos_incidence >= cos_limit)
        if robots is not None:
            directions = coarse.rays[rows, cols] @ optical[:3, :3].T.astype(np.float32)
            judged &= robots.depth(optical[:3, 3], directions) > virtual.depth
        pixels = np.bincount(virtual.tile[judged], minlength=len(scene.tile_ids)) * stride * stride
        resolves = tuple(
            tile
            for tile in wanted
            if tile in index_of and pixels[index_of[tile]] >= 2 * settings.min_observed_pixels
        )
        scores.append(ViewpointScore(pose, float(sum(wanted[t] for t in resolves)), resolves))
    return sorted(scores, key=lambda s: -s.score)


def next_viewpoint(
    scene: VirtualScene,
    low: np.ndarray,
    high: np.ndarray,
    camera: PinholeCamera,
    mount: CameraMount,
    candidates: Sequence[OverheadPose],
    unresolved: Iterable[int],
    priority: Iterable[int] = (),
    priority_weight: float = 3.0,
    current: OverheadPose | None = None,
    settings: EvidenceSettings | None = None,
    robots: RobotBoxes | None = None,
) -> ViewpointScore | None:
    """The candidate that resolves the most unresolved (and priority) tiles; None if none resolves any.

    Among equal scores the one nearest to `current` wins.
    """
    wanted: dict[int, float] = {int(t): 1.0 for t in unresolved}
    for tile in priority:
        wanted[int(tile)] = wanted.get(int(tile), 0.0) + priority_weight
    if not wanted or not candidates:
        return None
    ranked = rank_viewpoints(scene, low, high, camera, mount, candidates, wanted, settings, robots=robots)
    best = ranked[0].score
    if best <= 0:
        return None
    ties = [r for r in ranked if r.score >= best - 1e-9]
    if current is not None:
        ties.sort(key=lambda r: math.hypot(r.pose.x - current.x, r.pose.y - current.y))
    return ties[0]
