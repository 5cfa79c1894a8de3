"""Tiles a robot is placing: expected by the inspection, not judged (`tiles_in_hand`)."""

from __future__ import annotations

import numpy as np
from vi_helpers import structure

from tiling_sim.inspection_scenarios import Scene, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.classify import TileState
from vi_node.inspection_settings import InspectionSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_prior import OverheadPose
from vi_node.tiles_in_hand import TilesInHand

SECOND = 10**9


def test_a_tile_stays_in_hand_for_the_memory_after_the_last_status_placing_it() -> None:
    hand = TilesInHand(memory_ns=15 * SECOND)
    hand.heard(placing=True, tile_id=10, stamp_ns=100 * SECOND)
    hand.heard(placing=True, tile_id=10, stamp_ns=104 * SECOND)
    hand.heard(placing=False, tile_id=0, stamp_ns=105 * SECOND)  # the robot is waiting: nothing in hand
    assert hand.at(90 * SECOND) == {10}  # a status after the scan: it may already lie there
    assert hand.at(119 * SECOND) == {10}
    assert hand.at(120 * SECOND) == frozenset()
    assert hand.at(110 * SECOND, expected=[10]) == frozenset()  # reported placed: it is in S_a
    hand.forget_before(125 * SECOND)
    assert hand.at(0) == frozenset()


def test_a_tile_lying_there_before_its_placement_report_makes_no_neighbour_misplaced_when_in_hand() -> None:
    """Square 10 lies on the structure, its robot has not reported it yet: seen from this side, its
    points stand clear of every expected face at rectangle 11's height, which looks like a tile of
    the wrong type at 11. With 10 in hand, its faces explain them, and nothing is said of 10."""
    paper = structure()
    scene = Scene(paper, tuple(paper.tile_ids), ())
    reported = [t for t in paper.tile_ids if t != 10]
    view = view_from(scene.centre, 0.0, 1.0, np.random.default_rng(5))
    cloud = KinectSimulator(seed=6).scan(scene.kinect_scene, view.camera)
    pipeline = InspectionPipeline(paper, reported, InspectionSettings())

    def misplaced() -> tuple[list[int], list[int]]:
        result = pipeline.inspect(cloud, OverheadPose(*view.overhead))
        assert result.ok, result.reason
        assert 10 not in result.by_id() and 10 not in result.tile_ids and 10 not in result.misplacement
        assert result.evidence is not None and len(result.evidence.agree) == len(result.tile_ids) == 13
        return [t.tile_id for t in result.tiles if t.state is TileState.MISPLACED], list(result.tile_ids)

    flagged, _ = misplaced()
    assert flagged == [11]
    pipeline.set_expected(reported, in_hand=[10])
    assert pipeline.expected_ids == tuple(reported)
    flagged, judged = misplaced()
    assert flagged == []
    assert judged == reported
    pipeline.set_expected(reported, in_hand=[10, 3])  # 3 is reported placed: expected, and judged
    assert 3 in pipeline.expected_ids and pipeline.in_hand == {10}
