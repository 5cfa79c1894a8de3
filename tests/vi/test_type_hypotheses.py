"""A tile of another type in a tile's place, told from the planned one by the pixels where the two differ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vi_helpers import results_from, structure

from tiling_assembly.geometry import PlacedTile
from tiling_sim.inspection_scenarios import Scene, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.camera_model import PinholeCamera
from vi_node.classify import TileState
from vi_node.evidence import EvidenceSettings
from vi_node.misplacement import MisplacementSettings
from vi_node.pose_hypotheses import DepthImage
from vi_node.raycast import VirtualScene
from vi_node.type_hypotheses import TypeVotes, rival_tiles, tiles_box, type_votes

KINECT = PinholeCamera(580.0, 580.0, 319.5, 239.5, 640, 480)
RANGES = (0.5, 4.5)


def _swapped(tile_id: int, type_name: str) -> PlacedTile:
    paper = structure()
    tile = paper.tiles[tile_id]
    return PlacedTile(tile_id, type_name, paper.tile_types[type_name].shape, tile.rotation, tile.position)


def _votes(placed: dict[int, PlacedTile], tile_id: int, rival_type: str, bearing: float,
           masked: bool = False, removed: tuple[int, ...] = ()) -> TypeVotes:
    """Votes between the planned tile and `rival_type` on a simulated Kinect scan of paper_14 with
    the tiles `placed` instead of the planned ones and without the `removed`, from the true camera pose."""
    paper = structure()
    scene = Scene(paper, tuple(paper.tile_ids), removed, placed)
    view = view_from(scene.centre, math.radians(bearing), 1.0, np.random.default_rng(5))
    cloud = KinectSimulator(seed=6).scan(scene.kinect_scene, view.camera)
    tiles = [paper.tiles[i] for i in paper.tile_ids]
    index = list(paper.tile_ids).index(tile_id)
    rival = _swapped(tile_id, rival_type)
    window = KINECT.box_roi(view.camera, *tiles_box([tiles[index], rival]))
    mask = np.ones(cloud[window].shape[:2], dtype=bool) if masked else None
    image = DepthImage(cloud, KINECT, view.camera, window, mask)
    return type_votes(VirtualScene(tiles), index, rival, image, EvidenceSettings(), RANGES)


def test_rivals_are_the_other_types_of_the_same_height_at_the_planned_pose() -> None:
    paper = structure("pyramid_91")
    shapes = {name: kind.shape for name, kind in paper.tile_types.items()}
    for tile in paper.tiles.values():
        height = np.ptp(tile.shape.vertices[:, 2])
        for rival in rival_tiles(tile, shapes):
            assert rival.type_name != tile.type_name
            assert np.ptp(rival.shape.vertices[:, 2]) == pytest.approx(height, abs=1e-3)
            assert np.array_equal(rival.position, tile.position) and np.array_equal(rival.rotation, tile.rotation)
    square = structure().tiles[10]
    assert [r.type_name for r in rival_tiles(square, {n: t.shape for n, t in structure().tile_types.items()})] == [
        "long_rectangle", "octagon", "trapezoid", "triangle"]


@pytest.mark.parametrize("bearing", [60.0, 90.0, 120.0])
def test_a_triangle_where_a_square_was_planned_wins_the_pixels_where_they_differ(bearing: float) -> None:
    """The triangle covers 62% of the square's place: most of the square's pixels agree with it,
    but where the two shapes differ the depth is the triangle's."""
    settings = MisplacementSettings()
    wrong = _votes({10: _swapped(10, "triangle")}, 10, "triangle", bearing)
    assert wrong.rival_explains(settings.rival_share, settings.rival_pixels), wrong
    right = _votes({}, 10, "triangle", bearing)
    assert not right.rival_explains(settings.rival_share, settings.rival_pixels), right
    assert right.planned >= settings.rival_pixels and right.rival <= 0.25 * right.planned


@pytest.mark.parametrize("rival", ["long_rectangle", "octagon", "trapezoid", "triangle"])
def test_a_square_in_its_place_wins_against_every_other_type(rival: str) -> None:
    settings = MisplacementSettings()
    for bearing in (60.0, 120.0):
        votes = _votes({}, 10, rival, bearing)
        assert not votes.rival_explains(settings.rival_share, settings.rival_pixels), (bearing, votes)


@pytest.mark.parametrize("bearing", [60.0, 90.0, 120.0])
def test_a_tile_that_is_gone_is_no_smaller_tile_of_another_type(bearing: float) -> None:
    """With square 10 gone, the pixels of its place outside a triangle's footprint show what lies
    behind, as a triangle there would leave them; the triangle's own place is empty too."""
    settings = MisplacementSettings()
    gone = _votes({}, 10, "triangle", bearing, removed=(10,))
    assert gone.rival >= settings.rival_pixels  # what the pixels outside the triangle alone would say
    assert not gone.rival_explains(settings.rival_share, settings.rival_pixels), gone


@pytest.mark.parametrize("bearing", [0.0, 90.0, 180.0, 270.0])
def test_a_long_rectangle_that_is_gone_is_no_octagon(bearing: float) -> None:
    settings = MisplacementSettings()
    gone = _votes({}, 11, "octagon", bearing, removed=(11, 13))
    assert not gone.rival_explains(settings.rival_share, settings.rival_pixels), gone


def test_a_rival_out_of_sight_explains_nothing() -> None:
    """Scored on independent scenes, a removed long rectangle was called an octagon: the pixels of
    its place outside the octagon saw what lies behind it (49 for the octagon, 2 for the
    rectangle), and the octagon's own place was out of sight (one pixel of it in view), so nothing
    contradicted it. The rival must be seen on enough pixels, and seen where it would be."""
    settings = MisplacementSettings()
    assert not TypeVotes(planned=2, rival=49, rival_seen=1, rival_missed=0).rival_explains(
        settings.rival_share, settings.rival_pixels)
    assert TypeVotes(planned=2, rival=49, rival_seen=60, rival_missed=0).rival_explains(
        settings.rival_share, settings.rival_pixels)
    assert not TypeVotes(planned=2, rival=49, rival_seen=60, rival_missed=40).rival_explains(
        settings.rival_share, settings.rival_pixels)
    assert not TypeVotes(planned=20, rival=49, rival_seen=60, rival_missed=0).rival_explains(
        settings.rival_share, settings.rival_pixels)


def test_pixels_on_a_robot_vote_for_nothing() -> None:
    assert _votes({10: _swapped(10, "triangle")}, 10, "triangle", 90.0, masked=True) == TypeVotes(0, 0, 0, 0)


def test_the_pipeline_flags_a_triangle_where_a_square_was_planned_and_nothing_else() -> None:
    """Scored on independent scenes, a triangle in square 10's place was called present in most
    views: neither a refit nor 'something of another shape' (a third of its pixels seeing through)
    caught it."""
    paper = structure()
    results = results_from(Scene(paper, tuple(paper.tile_ids), (), {10: _swapped(10, "triangle")}), 10,
                           (45.0, 90.0, 135.0), seeds=(21, 22))
    states = [r.state for r in results]
    assert TileState.PRESENT not in states
    assert states.count(TileState.MISPLACED) >= 2
    # a scan that tells it by the two types' pixels names what lies there (for the repair's line on
    # /auction/decisions); one that flagged it some other way (a refit, another shape) names nothing
    assert "triangle" in {r.seen_type for r in results if r.state == TileState.MISPLACED}
    assert {r.seen_type for r in results} <= {"", "triangle"}
    assert {r.seen_type for r in results if r.state != TileState.MISPLACED} <= {""}
