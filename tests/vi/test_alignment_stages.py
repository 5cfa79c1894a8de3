"""The alignment stages one by one (paper section 2.2.1) on simulated scans with known truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vi_helpers import structure

from tiling_assembly.geometry import rotation_from_rpy, rpy_from_rotation
from tiling_sim.kinect import KinectNoise, KinectScene, KinectSimulator, camera_pose
from vi_node.camera_model import OPTICAL_FROM_LINK, PinholeCamera
from vi_node.candidates import select_candidates
from vi_node.coarse_alignment import CoarseAligner
from vi_node.floor import correct_pose, fit_floor
from vi_node.icp import Correspondences, point_to_plane_icp, yaw_shift_transform
from vi_node.patches import PlanarPatches
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior, pose_error
from vi_node.raycast import FLOOR, VirtualScene

MOUNT = CameraMount((0.08, 0.0, 0.55), (0.0, 0.45, 0.0))
CAMERA = PinholeCamera(580.0, 580.0, 319.5, 239.5, 640, 480)


def link_rpy(pose: np.ndarray) -> tuple[float, float, float]:
    return rpy_from_rotation(pose[:3, :3] @ OPTICAL_FROM_LINK.T)


def test_pose_prior_composes_overhead_pose_mount_and_optical_frame() -> None:
    prior = camera_prior(OverheadPose(1.0, 2.0, math.pi / 2), MOUNT)
    # base faces +y; the camera sits 8 cm ahead of it, 55 cm up, looking forward and 0.45 rad down
    assert np.allclose(prior[:3, 3], [1.0, 2.08, 0.55])
    forward, right, down = prior[:3, 2], prior[:3, 0], prior[:3, 1]
    assert np.allclose(forward, [0.0, math.cos(0.45), -math.sin(0.45)], atol=1e-12)
    assert np.allclose(right, [1.0, 0.0, 0.0], atol=1e-12)  # right of a robot facing +y is +x
    assert down[2] < -0.8
    assert np.allclose(link_rpy(prior), (0.0, 0.45, math.pi / 2))


def test_overhead_pose_from_a_quaternion_keeps_only_the_yaw() -> None:
    q = rotation_from_rpy(0.1, -0.2, 0.7)
    from tiling_assembly.geometry import quaternion_from_rotation

    pose = OverheadPose.from_quaternion(0.5, -0.5, *quaternion_from_rotation(q))
    assert pose.yaw == pytest.approx(0.7)


def test_floor_correction_fixes_height_roll_pitch_and_keeps_yaw_and_position() -> None:
    truth = camera_pose(0.3, -0.2, 0.4, MOUNT.xyz, MOUNT.rpy, base_z=0.012, base_roll=0.03, base_pitch=-0.025)
    cloud = KinectSimulator(seed=1).scan(KinectScene(), truth)
    prior = camera_prior(OverheadPose(0.33, -0.18, 0.4 + math.radians(8.0)), MOUNT)
    floor = fit_floor(cloud, prior, np.array([5.0, 5.0, 0.0]), np.array([5.1, 5.1, 0.1]))
    assert floor is not None and floor.points > 500
    corrected = correct_pose(prior, floor)
    assert corrected[2, 3] == pytest.approx(truth[2, 3], abs=0.002)
    assert np.allclose(corrected[:2, 3], prior[:2, 3])  # x, y untouched
    roll, pitch, yaw = link_rpy(corrected)
    true_roll, true_pitch, _ = link_rpy(truth)
    assert yaw == pytest.approx(link_rpy(prior)[2], abs=1e-9)  # yaw untouched
    assert roll == pytest.approx(true_roll, abs=math.radians(0.15))
    assert pitch == pytest.approx(true_pitch, abs=math.radians(0.15))
    # the corrected camera sees the floor exactly where it is: at z = 0
    up = corrected[:3, :3].T @ np.array([0.0, 0.0, 1.0])
    assert np.allclose(up, floor.normal, atol=1e-9)


def test_no_floor_in_view_gives_no_fit() -> None:
    level = camera_pose(0.0, 0.0, 0.0, (0.0, 0.0, 0.55), (0.0, -0.6, 0.0))  # looking up at the sky
    cloud = KinectSimulator(seed=2).scan(KinectScene(), level)
    assert fit_floor(cloud, level, np.zeros(3), np.ones(3)) is None


def test_patch_projection_matches_a_brute_force_closest_point() -> None:
    paper = structure()
    tiles = list(paper.tiles.values())
    patches = PlanarPatches(tiles)
    scene = VirtualScene(tiles)
    rng = np.random.default_rng(3)
    low, high = paper.bounds
    points = rng.uniform(low - 0.02, high + 0.02, size=(2000, 3))
    projection = patches.project(points, 0.05)
    closest, _, _ = scene.closest_points(points)
    reference = np.linalg.norm(points - closest, axis=1)
    found = projection.found
    assert found.sum() > 1500
    assert np.allclose(projection.distance[found], reference[found], atol=1e-6)
    assert np.all(reference[~found] > 0.05 - 1e-6)  # none missed within the distance asked for
    assert np.allclose(
        np.linalg.norm(projection.closest[found] - points[found], axis=1), projection.distance[found]
    )


def test_hierarchy_skips_far_points_and_faces_turned_away() -> None:
    paper = structure()
    patches = PlanarPatches(list(paper.tiles.values()))
    far = patches.project(np.array([[1.0, 1.0, 1.0]]), 0.05)
    assert not far.found.any()
    # a point where square 9 meets trapezoid 6: the camera above sees 6's top, not 9's bottom
    point = np.array([[-0.125, 0.0, 0.02]])
    above = np.array([-0.125, 0.0, 1.0])
    index = {int(t): k for k, t in enumerate(patches.tile_ids)}
    seen = patches.project(point, 0.01, camera_position=above)
    assert seen.tile[0] == index[6] and np.allclose(seen.normal[0], [0, 0, 1])
    below = patches.project(point, 0.01, camera_position=np.array([-0.125, 0.0, -1.0]))
    assert below.tile[0] == index[9] and np.allclose(below.normal[0], [0, 0, -1])


def structure_points(seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Points an ideal Kinect sees of the paper structure, and the camera pose."""
    paper = structure()
    pose = camera_pose(-0.8, -0.7, math.radians(40.0), MOUNT.xyz, MOUNT.rpy)
    cloud, labels = KinectSimulator(seed=seed, noise=KinectNoise(lateral=False)).scan_labelled(
        KinectScene.from_structure(paper), pose
    )
    points = cloud[labels > 0].astype(float) @ pose[:3, :3].T + pose[:3, 3]
    return points, pose


def test_point_to_plane_icp_recovers_a_small_offset_within_10_iterations() -> None:
    points, pose = structure_points(4)
    patches = PlanarPatches(list(structure().tiles.values()))
    offset = yaw_shift_transform(math.radians(1.5), np.array([0.0, 0.0, 0.0]), np.array([0.008, -0.006]))
    moved = points @ offset[:3, :3].T + offset[:3, 3]

    def correspond(p: np.ndarray, cut: float) -> Correspondences:
        projection = patches.project(p, cut, pose[:3, 3])
        return Correspondences(projection.closest, projection.normal, projection.distance)

    result = point_to_plane_icp(moved, correspond)
    assert result.iterations <= 10
    recovered = result.correction @ offset
    shift, turn = pose_error(recovered, np.eye(4))
    assert shift < 0.002 and turn < math.radians(0.1)
    assert result.rms < 0.004


def test_coarse_search_undoes_overhead_sized_errors() -> None:
    points, pose = structure_points(5)
    paper = structure()
    scene = VirtualScene(list(paper.tiles.values()))
    low, high = paper.bounds
    aligner = CoarseAligner(scene, low, high, 0.01)
    points = points[points[:, 2] > 0.01]
    error = yaw_shift_transform(math.radians(-9.0), pose[:3, 3], np.array([0.04, -0.03]))
    result = aligner.align(points @ error[:3, :3].T + error[:3, 3], pose[:3, 3])
    assert result is not None and result.on_surface > 0.8
    residual = result.correction @ error
    shift, turn = pose_error(residual, np.eye(4))
    assert turn < math.radians(1.6)
    assert np.linalg.norm((points @ residual[:3, :3].T + residual[:3, 3]) - points, axis=1).max() < 0.02
    assert shift < 0.05  # (about the camera, 1 m away: turn and shift go together)


def test_candidates_are_the_points_in_the_structure_box_above_the_floor() -> None:
    paper = structure()
    pose = camera_pose(-0.8, -0.7, math.radians(40.0), MOUNT.xyz, MOUNT.rpy)
    cloud, labels = KinectSimulator(seed=6).scan_labelled(KinectScene.from_structure(paper), pose)
    low, high = paper.bounds
    chosen = select_candidates(cloud, CAMERA, pose, low, high, 0.03, 0.01)
    flat_labels = labels.reshape(-1)[chosen.pixels]
    assert (flat_labels > 0).mean() > 0.97  # nearly all on tiles, the floor is gone
    assert (flat_labels > 0).sum() > 0.9 * ((labels > 0) & (cloud[..., 2] > 0)).sum() * 0.8
    assert np.allclose(chosen.optical, cloud.reshape(-1, 3)[chosen.pixels], atol=1e-6)
    assert chosen.points[:, 2].min() >= 0.01


def test_virtual_scan_matches_the_simulated_kinect_without_noise() -> None:
    paper = structure()
    pose = camera_pose(0.9, 0.5, math.radians(-150.0), MOUNT.xyz, MOUNT.rpy)
    cloud, labels = KinectSimulator(noise=KinectNoise.ideal()).scan_labelled(
        KinectScene.from_structure(paper), pose
    )
    scene = VirtualScene(list(paper.tiles.values()))
    rows, cols = CAMERA.box_roi(pose, *paper.bounds)
    virtual = scene.cast(CAMERA, pose, rows, cols, 0.5, 4.5)
    ids = np.where(
        virtual.tile >= 0, scene.tile_ids[np.maximum(virtual.tile, 0)], np.where(virtual.tile == FLOOR, 0, -2)
    )
    window = labels[rows, cols]
    assert (ids == window).mean() > 0.999
    assert (window > 0).sum() == (labels > 0).sum()  # the window holds every structure pixel
    depth = cloud[rows, cols, 2]
    both = np.isfinite(depth) & np.isfinite(virtual.depth)
    assert np.allclose(depth[both], virtual.depth[both], atol=1e-4)


def test_icp_does_not_slide_along_what_the_view_leaves_free() -> None:
    """Points on two parallel faces (normals along x) and the floor fix x, z, roll, pitch and yaw
    but not y: one stray point off a y-facing face must not drag the pose along y."""
    rng = np.random.default_rng(5)
    faces = np.array([[x, y, z] for x in (0.0, 0.04) for y in np.linspace(-0.1, 0.1, 21) for z in (0.01, 0.03)])
    floor = np.column_stack([rng.uniform(-0.3, 0.3, 200), rng.uniform(-0.3, 0.3, 200), np.zeros(200)])
    stray = np.array([[0.02, 0.15, 0.02]])  # 1 cm in front of a face at y = 0.14 the model has
    points = np.vstack([faces, floor, stray])

    def correspond(p: np.ndarray, cut: float) -> Correspondences:
        closest, normal = p.copy(), np.zeros_like(p)
        on_faces = np.arange(len(p)) < len(faces)
        on_floor = (np.arange(len(p)) >= len(faces)) & (np.arange(len(p)) < len(p) - 1)
        closest[on_faces, 0] = np.where(p[on_faces, 0] < 0.02, 0.0, 0.04)
        normal[on_faces] = (1.0, 0.0, 0.0)
        closest[on_floor, 2], normal[on_floor] = 0.0, (0.0, 0.0, 1.0)
        closest[-1, 1], normal[-1] = 0.14, (0.0, 1.0, 0.0)
        return Correspondences(closest, normal, np.linalg.norm(p - closest, axis=1))

    result = point_to_plane_icp(points, correspond)
    assert abs(result.correction[1, 3]) < 1e-4  # y: free, stays
    assert np.allclose(result.correction[:3, :3], np.eye(3), atol=1e-3)


def test_the_x_y_yaw_search_looks_sideways_of_the_structure_but_not_in_front_of_it() -> None:
    """A yaw error turns the structure about the camera: sideways by a third of a metre at 1.5 m,
    never nearer or farther. Clutter half a metre in front of S_a is left out of the search."""
    from vi_node.candidates import at_structure_range

    low, high = np.array([-0.15, -0.05, 0.0]), np.array([0.15, 0.05, 0.04])
    camera = np.array([-1.5, 0.0])
    points = np.array(
        [
            [0.0, 0.0, 0.02],  # on the structure
            [0.0, 0.30, 0.02],  # where a 11 degree yaw error puts it
            [-0.55, 0.0, 0.1],  # a box in front of it
            [0.60, 0.0, 0.1],  # a robot behind it
        ]
    )
    assert at_structure_range(points, camera, low, high, margin=0.13).tolist() == [True, True, False, False]
