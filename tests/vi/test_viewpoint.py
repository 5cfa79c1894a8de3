"""Next viewpoint: ray-trace candidate poses, pick the one that resolves the most wanted tiles."""

from __future__ import annotations

import math

import numpy as np
from vi_helpers import structure

from vi_node.camera_model import PinholeCamera
from vi_node.patches import PlanarPatches
from vi_node.pose_prior import CameraMount, OverheadPose
from vi_node.raycast import VirtualScene
from vi_node.viewpoint import next_viewpoint, rank_viewpoints

CAMERA = PinholeCamera(580.0, 580.0, 319.5, 239.5, 640, 480)
MOUNT = CameraMount((0.08, 0.0, 0.55), (0.0, 0.45, 0.0))


def around(bearings_deg: list[float], distance: float = 1.0) -> list[OverheadPose]:
    """Robot poses on a circle around the origin, facing it."""
    poses = []
    for b in bearings_deg:
        a = math.radians(b)
        poses.append(OverheadPose(distance * math.cos(a), distance * math.sin(a), a + math.pi))
    return poses


def model() -> tuple[VirtualScene, np.ndarray, np.ndarray]:
    tiles = list(structure().tiles.values())
    patches = PlanarPatches(tiles)
    return VirtualScene(tiles), patches.low, patches.high


def test_the_pose_that_sees_the_unresolved_tile_wins() -> None:
    scene, low, high = model()
    candidates = around([180.0, 0.0])  # from the -x end, trapezoid 7 at the +x end is out of sight
    best = next_viewpoint(scene, low, high, CAMERA, MOUNT, candidates, unresolved=[7])
    assert best is not None and best.pose == candidates[1] and best.resolves == (7,)
    ranked = rank_viewpoints(scene, low, high, CAMERA, MOUNT, candidates, {7: 1.0})
    assert [r.score for r in ranked] == [1.0, 0.0]


def test_priority_tiles_weigh_more_and_ties_go_to_the_nearest_pose() -> None:
    scene, low, high = model()
    candidates = around([180.0, 0.0])
    best = next_viewpoint(scene, low, high, CAMERA, MOUNT, candidates, unresolved=[6], priority=[7])
    assert best is not None and best.pose == candidates[1]  # the priority tile outweighs
    both = around([-90.0, 90.0])  # both long sides see the whole top layer
    near = next_viewpoint(
        scene, low, high, CAMERA, MOUNT, both, unresolved=[11, 12], current=OverheadPose(0.1, 1.5, 0.0)
    )
    assert near is not None and near.pose == both[1]


def test_no_candidate_resolves_a_tile_nothing_can_see() -> None:
    scene, low, high = model()
    assert (
        next_viewpoint(scene, low, high, CAMERA, MOUNT, around([0.0, 90.0, 180.0, 270.0]), unresolved=[3])
        is None
    )
    assert next_viewpoint(scene, low, high, CAMERA, MOUNT, [], unresolved=[8]) is None


def test_a_pose_facing_away_from_the_structure_scores_nothing() -> None:
    """Its view of the structure's box is empty (no pixel at all): the explorer of a 4.8 m arcade
    crashed on it ("index 0 is out of bounds for axis 1 with size 0")."""
    scene, low, high = model()
    away = OverheadPose(1.0, 0.0, math.pi / 2)  # one metre out on +x, looking past the structure
    ranked = rank_viewpoints(scene, low, high, CAMERA, MOUNT, [away, *around([0.0])], {7: 1.0})
    assert [r.score for r in ranked] == [1.0, 0.0] and ranked[1].pose == away
