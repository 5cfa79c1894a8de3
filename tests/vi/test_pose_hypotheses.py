"""The tile where it should be against where its points put it, pixel by pixel (vi_node.pose_hypotheses)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vi_helpers import structure

from tiling_sim.inspection_scenarios import Scene, misplace_tile, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.inspection_settings import InspectionSettings
from vi_node.misplacement import MisplacementSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_hypotheses import DepthImage, PosePixels, fitted_pose_explains, pixels_at_fitted_pose

TRIANGLE = 13  # on long rectangle 11, the top layer: 5 cm, little of it covers its place once shifted 4.5 cm


def _pixels(scene: Scene, offset: tuple[float, float, float], seed: int = 3) -> tuple[PosePixels, PosePixels]:
    """The triangle's pixels at its planned pose and moved by `offset`, in one scan of `scene`."""
    paper = scene.structure
    pipeline = InspectionPipeline(paper, None, InspectionSettings())
    view = view_from(scene.centre, math.radians(120.0), 0.9, np.random.default_rng(seed))
    cloud = KinectSimulator(seed=seed).scan(scene.kinect_scene, view.camera)
    model = pipeline.model
    image = DepthImage(cloud, pipeline.camera, view.camera, pipeline.camera.box_roi(view.camera, model.low, model.high))
    settings, ranges = pipeline.evidence_settings, (pipeline.settings.min_range, pipeline.settings.max_range)
    index = model.tile_ids.index(TRIANGLE)
    planned = pixels_at_fitted_pose(model.tiles, index, (0.0, 0.0, 0.0), image, settings, ranges)
    moved = pixels_at_fitted_pose(model.tiles, index, offset, image, settings, ranges)
    return planned, moved


@pytest.fixture(scope="module")
def shifted() -> tuple[Scene, tuple[float, float, float]]:
    paper = structure()
    others = [t for t in paper.tile_ids if t != TRIANGLE]
    moved = misplace_tile(paper, TRIANGLE, others, np.random.default_rng(4), shift=(0.045, 0.045))
    assert moved is not None
    dx, dy = moved.centroid[:2] - paper.tiles[TRIANGLE].centroid[:2]
    return Scene(paper, tuple(paper.tile_ids), (), {TRIANGLE: moved}), (float(dx), float(dy), 0.0)


def test_a_tile_that_slipped_far_is_explained_where_it_lies_and_not_where_it_should_be(shifted) -> None:  # type: ignore[no-untyped-def]
    scene, offset = shifted
    planned, moved = _pixels(scene, offset)
    settings = MisplacementSettings()
    assert planned.against > planned.agree  # alone, its planned pose's pixels say "missing"
    assert moved.decisive >= settings.fitted_pixels and moved.agree >= 0.8 * moved.decisive
    assert fitted_pose_explains(planned.agree, moved, settings.fitted_share, settings.fitted_gain,
                                settings.fitted_pixels)


def test_a_tile_that_is_gone_is_explained_at_no_pose(shifted) -> None:  # type: ignore[no-untyped-def]
    """A refit can slide a tile that is gone onto surfaces nearby; the depth image at that pose shows
    what lies behind it instead."""
    scene, offset = shifted
    paper = scene.structure
    gone = Scene(paper, tuple(paper.tile_ids), (TRIANGLE,))
    planned, moved = _pixels(gone, offset)
    settings = MisplacementSettings()
    assert moved.against > moved.agree
    assert not fitted_pose_explains(planned.agree, moved, settings.fitted_share, settings.fitted_gain,
                                    settings.fitted_pixels)


def test_the_fitted_pose_must_explain_clearly_more_than_the_planned_one() -> None:
    few = PosePixels(agree=20, against=0)
    assert not fitted_pose_explains(0, few, 0.7, 0.25, 30)  # too few pixels to tell
    split = PosePixels(agree=60, against=40)
    assert not fitted_pose_explains(0, split, 0.7, 0.25, 30)  # the fitted pose is no better explained
    both = PosePixels(agree=90, against=10)
    assert not fitted_pose_explains(80, both, 0.7, 0.25, 30)  # the planned pose explains nearly as much
    assert fitted_pose_explains(20, both, 0.7, 0.25, 30)
