"""How well a camera pose explains the depth image (vi_node.view_agreement): the true pose sees
through no tile; a pose a few centimetres and degrees off, which puts the scan's points onto S_a's
flat tops just as well, sees through dozens of the pixels sampled."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vi_helpers import structure

from tiling_sim.inspection_scenarios import Scene, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.evidence import EvidenceSettings
from vi_node.icp import yaw_shift_transform
from vi_node.inspection_settings import InspectionSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_prior import pose_error
from vi_node.view_agreement import DepthView, ViewAgreement, climb, view_agreement

RANGES = (0.5, 4.5)


@pytest.fixture(scope="module")
def first_layer() -> tuple[InspectionPipeline, DepthView, np.ndarray]:
    """The paper's three flat tiles of the first layer (long rectangles 1-3), seen from 1 m."""
    paper = structure()
    scene = Scene(paper, (1, 2, 3), ())
    view = view_from(scene.centre, math.radians(30.0), 1.0, np.random.default_rng(7))
    cloud = KinectSimulator(seed=7).scan(scene.kinect_scene, view.camera)
    pipeline = InspectionPipeline(paper, (1, 2, 3), InspectionSettings())
    return pipeline, DepthView(cloud, pipeline.camera), view.camera


def _agreement(pipeline: InspectionPipeline, view: DepthView, pose: np.ndarray):  # type: ignore[no-untyped-def]
    model = pipeline.model
    return view_agreement(view, model.scene, pose, (model.low, model.high), RANGES, EvidenceSettings())


def test_the_true_pose_sees_through_no_tile(first_layer) -> None:  # type: ignore[no-untyped-def]
    pipeline, view, truth = first_layer
    agreement = _agreement(pipeline, view, truth)
    assert agreement.agree > 150
    assert agreement.behind <= 0.02 * agreement.agree


@pytest.mark.parametrize("turn, shift", [(6.0, (0.0, 0.0)), (0.0, (0.05, 0.0)), (-5.0, (0.02, -0.04))])
def test_a_pose_centimetres_off_sees_through_tiles_and_scores_lower(first_layer, turn, shift) -> None:  # type: ignore[no-untyped-def]
    pipeline, view, truth = first_layer
    wrong = yaw_shift_transform(math.radians(turn), truth[:3, 3], np.array(shift)) @ truth
    right, off = _agreement(pipeline, view, truth), _agreement(pipeline, view, wrong)
    assert off.behind >= 30 and off.behind >= 10 * right.behind
    assert off.score(3.0) < right.score(3.0)


def test_masked_pixels_and_blanks_say_nothing(first_layer) -> None:  # type: ignore[no-untyped-def]
    pipeline, view, truth = first_layer
    everything = np.ones(view.cloud.shape[:2], dtype=bool)
    masked = DepthView(view.cloud, view.camera, everything)
    blank = DepthView(np.full_like(view.cloud, np.nan), view.camera)
    for agreement in (_agreement(pipeline, masked, truth), _agreement(pipeline, blank, truth)):
        assert agreement.agree == agreement.behind == 0 and agreement.score(3.0) == 0.0


def test_a_tile_seen_through_costs_the_pose_at_most_nothing() -> None:
    """A tile may be gone: its seen-through pixels cancel its own agreeing ones, not the other tiles'."""
    agreement = ViewAgreement(np.array([120, 10, 0]), np.array([2, 300, 0]))
    assert agreement.agree == 130 and agreement.behind == 302
    assert agreement.score(1.0) == 118.0
    assert agreement.score(3.0) == 114.0


@pytest.mark.parametrize("turn, shift", [(0.0, (0.0, 0.025)), (0.0, (-0.02, 0.01)), (1.0, (0.0, 0.02))])
def test_a_pose_a_few_centimetres_off_climbs_back_to_the_truth(first_layer, turn, shift) -> None:  # type: ignore[no-untyped-def]
    """Where ICP on a few faces stopped a couple of centimetres off, the pixels seen through pull it
    most of the way back (on three flat tiles a degree of yaw and a centimetre sideways nearly trade
    off: the ICP that follows the climb in the pipeline ends it)."""
    pipeline, view, truth = first_layer
    wrong = yaw_shift_transform(math.radians(turn), truth[:3, 3], np.array(shift)) @ truth
    climbed, score = climb(wrong, lambda pose: _agreement(pipeline, view, pose).score(3.0))
    error, off = pose_error(climbed, truth), pose_error(wrong, truth)
    assert error[0] <= min(0.015, 0.75 * off[0]) and error[1] <= math.radians(1.1)
    assert score > _agreement(pipeline, view, wrong).score(3.0)


def test_climbing_from_the_truth_stays_there(first_layer) -> None:  # type: ignore[no-untyped-def]
    pipeline, view, truth = first_layer
    climbed, _ = climb(truth, lambda pose: _agreement(pipeline, view, pose).score(3.0))
    shift, turn = pose_error(climbed, truth)
    assert shift <= 0.011 and turn <= math.radians(0.6)
