"""The Kinect v1 simulator: optical frame convention, noise model, dropouts, shadows, resolution."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vi_helpers import structure

from tiling_sim.kinect import (
    CLUTTER_LABEL,
    FLOOR_LABEL,
    KINECT_V1_DEPTH,
    NO_RETURN_LABEL,
    ClutterBox,
    KinectNoise,
    KinectScene,
    KinectSimulator,
    camera_pose,
)

LEVEL = camera_pose(0.0, 0.0, 0.0, (0.0, 0.0, 0.5), (0.0, 0.0, 0.0))  # 0.5 m high, looking along +x


def wall(distance: float) -> ClutterBox:
    return ClutterBox((distance + 0.05, 0.0, 0.5), (0.1, 6.0, 3.0))


def test_optical_frame_is_z_forward_x_right_y_down() -> None:
    scene = KinectScene(
        clutter=[ClutterBox((1.0, 0.3, 0.5), (0.1, 0.1, 0.1))], floor=False
    )  # ahead, to the left
    cloud, labels = KinectSimulator(noise=KinectNoise.ideal()).scan_labelled(scene, LEVEL)
    rows, cols = np.nonzero(labels == CLUTTER_LABEL)
    assert len(rows) > 100
    assert cols.max() < KINECT_V1_DEPTH.cx  # left in the image ...
    points = cloud[rows, cols]
    assert np.all(points[:, 0] < 0)  # ... is -x in the optical frame
    assert (
        abs(np.median(points[:, 2]) - 0.95) < 1e-4 and points[:, 2].min() > 0.95 - 1e-4
    )  # depth of its face
    assert abs(np.median(points[:, 1])) < 0.01  # at camera height: y ~ 0 (y points down)


def test_points_are_rebuilt_from_pixel_and_depth_like_a_driver() -> None:
    cloud = KinectSimulator(seed=1).scan(KinectScene(clutter=[wall(1.5)], floor=False), LEVEL)
    k = KINECT_V1_DEPTH
    v, u = np.mgrid[0 : k.height, 0 : k.width]
    ok = np.isfinite(cloud[..., 2])
    assert np.allclose(cloud[..., 0][ok], ((u - k.cx) * cloud[..., 2] / k.fx)[ok], atol=1e-5)
    assert np.allclose(cloud[..., 1][ok], ((v - k.cy) * cloud[..., 2] / k.fy)[ok], atol=1e-5)


@pytest.mark.parametrize("distance", [1.0, 2.0])
def test_axial_noise_and_disparity_quantisation_follow_the_model(distance: float) -> None:
    simulator = KinectSimulator(seed=2, noise=KinectNoise(lateral=False, shadow=False, edge_dropout=0.0))
    cloud = simulator.scan(KinectScene(clutter=[wall(distance)], floor=False), LEVEL)
    depth = cloud[200:280, 280:360, 2]
    sigma = 0.0012 + 0.0019 * (distance - 0.4) ** 2
    step = 2.85e-3 * distance**2
    spread = float(np.nanstd(depth))
    assert math.sqrt(sigma**2 + step**2 / 12) * 0.7 < spread < math.sqrt(sigma**2 + step**2 / 12) * 1.4
    assert abs(float(np.nanmean(depth)) - distance) < 0.3 * step + 0.001
    levels = np.unique(np.round(depth[np.isfinite(depth)], 4))
    gaps = np.diff(levels)
    assert gaps.min() > 0.6 * step  # depths come in disparity steps (2.9 mm at 1 m, 11 mm at 2 m)


def test_projector_shadow_falls_left_of_an_object() -> None:
    scene = KinectScene(clutter=[wall(2.0), ClutterBox((1.0, 0.0, 0.5), (0.04, 0.04, 1.0))], floor=False)
    ideal = KinectSimulator(noise=KinectNoise.ideal()).scan(scene, LEVEL)
    shadowed = KinectSimulator(
        noise=KinectNoise(lateral=False, axial=False, edge_dropout=0.0, speckle_dropout=0.0)
    ).scan(scene, LEVEL)
    row = 240
    pole = np.flatnonzero(ideal[row, :, 2] < 1.5)
    lost = np.flatnonzero(np.isnan(shadowed[row, :, 2]))
    assert len(lost) >= 10
    assert lost.max() < pole.min() and lost.min() > pole.min() - 40  # a band just left of the pole
    assert not np.isnan(shadowed[row, pole.max() + 1 : pole.max() + 40, 2]).any()


def test_range_limits_and_grazing_floor() -> None:
    pose = camera_pose(0.0, 0.0, 0.0, (0.0, 0.0, 0.55), (0.0, 0.45, 0.0))
    cloud, labels = KinectSimulator(seed=3).scan_labelled(KinectScene(), pose)
    depth = cloud[..., 2]
    assert np.nanmin(depth) >= 0.5 - 0.02 and np.nanmax(depth) <= 4.5 + 0.25  # + noise and quantisation
    near = np.isfinite(depth[400:, :]).mean()
    far = np.isfinite(depth[:60, :]).mean()
    assert near > 0.95 and far < near  # the floor thins out where rays graze it
    assert set(np.unique(labels)) <= {FLOOR_LABEL, NO_RETURN_LABEL}


def test_labels_name_the_tiles_that_were_hit_and_scenes_are_reusable() -> None:
    paper = structure()
    scene = KinectScene.from_structure(paper, present=[1, 2, 3, 6, 7])
    pose = camera_pose(1.0, 0.0, math.pi, (0.08, 0.0, 0.55), (0.0, 0.45, 0.0))
    simulator = KinectSimulator(seed=4)
    _, first = simulator.scan_labelled(scene, pose)
    _, second = simulator.scan_labelled(scene, pose)
    seen = set(np.unique(first[first > 0]).tolist())
    assert seen and seen <= {1, 2, 3, 6, 7}
    assert 7 in seen  # the trapezoid nearest to the camera
    on_tiles = first > 0
    assert (first[on_tiles] == second[on_tiles]).mean() > 0.8  # same scene, new noise


def test_same_seed_same_cloud_and_other_resolutions() -> None:
    scene = KinectScene.from_structure(structure())
    pose = camera_pose(0.0, -1.2, math.pi / 2, (0.08, 0.0, 0.55), (0.0, 0.45, 0.0))
    a = KinectSimulator(seed=5).scan(scene, pose)
    b = KinectSimulator(seed=5).scan(scene, pose)
    assert np.array_equal(a, b, equal_nan=True)
    small = KinectSimulator(KINECT_V1_DEPTH.scaled(320, 240), seed=5).scan(scene, pose)
    assert small.shape == (240, 320, 3) and small.dtype == np.float32
    assert abs(np.nanmedian(small[..., 2]) - np.nanmedian(a[..., 2])) < 0.05


def test_pixels_showing_a_tile_counts_what_is_in_range_and_in_front_and_draws_no_random_numbers() -> None:
    tile = structure("paper_14").tiles[1]
    at = tile.vertices.mean(axis=0)
    simulator = KinectSimulator(seed=5)
    state = simulator.rng.bit_generator.state

    def looking_from(distance: float) -> np.ndarray:
        return camera_pose(at[0] - distance, at[1], 0.0, (0.0, 0.0, at[2] + 0.3), (0.0, math.atan2(0.3, distance), 0.0))

    seen = simulator.pixels_showing(KinectScene([tile]), looking_from(1.0), tile.tile_id)
    assert seen > 400
    assert simulator.pixels_showing(KinectScene([tile]), looking_from(0.3), tile.tile_id) == 0  # nearer than 0.5 m
    in_front = ClutterBox((at[0] - 0.5, at[1], 0.5), (0.1, 1.0, 1.0))
    assert simulator.pixels_showing(KinectScene([tile], [in_front]), looking_from(1.0), tile.tile_id) == 0
    assert simulator.rng.bit_generator.state == state
