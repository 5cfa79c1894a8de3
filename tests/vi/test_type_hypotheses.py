"""A tile of another type in a tile's place, told from the planned one by the pixels where the two differ."""

from __future__ import annotations

import math

import numpy as np
import pytest
from vi_helpers import results_from, states_from, structure

from tiling_assembly.geometry import PlacedTile, prism_shape
from tiling_sim.inspection_scenarios import Scene, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.camera_model import PinholeCamera
from vi_node.classify import TileState
from vi_node.evidence import EvidenceSettings
from vi_node.misplacement import MisplacementSettings
from vi_node.pose_hypotheses import DepthImage
from vi_node.raycast import VirtualScene
from vi_node.type_hypotheses import TypeVotes, look_alike_rivals, rival_tiles, tiles_box, type_votes

KINECT = PinholeCamera(580.0, 580.0, 319.5, 239.5, 640, 480)
RANGES = (0.5, 4.5)


def _swapped(tile_id: int, type_name: str) -> PlacedTile:
    paper = structure()
    tile = paper.tiles[tile_id]
    return PlacedTile(tile_id, type_name, paper.tile_types[type_name].shape, tile.rotation, tile.position)


def _votes(placed: dict[int, PlacedTile], tile_id: int, rival_type: str, bearing: float,
           masked: bool = False, removed: tuple[int, ...] = (), reuse: str = "") -> TypeVotes:
    """Votes between the planned tile and `rival_type` on a simulated Kinect scan of paper_14 with
    the tiles `placed` instead of the planned ones and without the `removed`, from the true camera
    pose. `reuse`: cast S_a over the whole image first and hand the votes its part over their
    window, with nothing behind it looked at ("front"), or what lies behind every other row ("rows")."""
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
    scene = VirtualScene(tiles)
    cast = None
    if reuse:
        whole = scene.cast(KINECT, view.camera, slice(0, 480), slice(0, 640), *RANGES)
        if reuse == "rows":
            every_other_row = np.zeros(whole.tile.shape, dtype=bool)
            every_other_row[::2] = True
            whole = scene.look_behind(whole, KINECT, view.camera, where=every_other_row)
        cast = whole.within(*window)
    return type_votes(scene, index, rival, image, EvidenceSettings(), RANGES, cast=cast)


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


def test_look_alike_rivals_share_half_the_union_of_the_two_footprints() -> None:
    paper = structure()
    shapes = {name: kind.shape for name, kind in paper.tile_types.items()}
    alike = {paper.tiles[t].type_name: [r.type_name for r in look_alike_rivals(paper.tiles[t], shapes, 0.5)]
             for t in (1, 4, 6, 10, 13)}
    assert alike == {"long_rectangle": [], "octagon": ["trapezoid"], "trapezoid": ["octagon"],
                     "square": ["triangle"], "triangle": ["square"]}
    # an L-shaped tile (8 cm square less a 4 cm corner: 48 cm2, not convex) and squares of its height
    corner = np.array([[0.0, 0.0], [0.08, 0.0], [0.08, 0.04], [0.04, 0.04], [0.04, 0.08], [0.0, 0.08]])
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    kinds = {"ell": prism_shape(corner, 0.02), "big": prism_shape(0.08 * square, 0.02),
             "small": prism_shape(0.04 * square, 0.02)}
    ell = PlacedTile(1, "ell", kinds["ell"], np.eye(3), np.zeros(3))
    assert [r.type_name for r in look_alike_rivals(ell, kinds, 0.5)] == ["big"]  # 48 of 64; the small: 16 of 48


def test_a_rival_as_likely_needs_a_pixel_and_no_fewer_than_the_planned_type() -> None:
    assert TypeVotes(planned=0, rival=1).rival_as_likely(1)
    assert TypeVotes(planned=3, rival=3).rival_as_likely(1)
    assert not TypeVotes(planned=4, rival=3).rival_as_likely(1)
    assert not TypeVotes(planned=0, rival=0).rival_as_likely(1)


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


@pytest.mark.parametrize("reuse", ["front", "rows"])
def test_votes_on_the_scans_own_cast_are_those_on_a_fresh_one(reuse: str) -> None:
    triangle = _swapped(10, "triangle")
    for placed, rival in (({10: triangle}, "triangle"), ({}, "octagon")):
        fresh = _votes(placed, 10, rival, 20.0)
        assert fresh.planned + fresh.rival > 10
        assert _votes(placed, 10, rival, 20.0, reuse=reuse) == fresh


def test_a_cast_is_cut_to_a_window_inside_it_and_to_none_beyond() -> None:
    paper = structure()
    view = view_from(Scene(paper, tuple(paper.tile_ids), ()).centre, 0.3, 1.0, np.random.default_rng(5))
    whole = VirtualScene([paper.tiles[i] for i in paper.tile_ids]).cast(
        KINECT, view.camera, slice(100, 300), slice(200, 500), *RANGES)
    part = whole.within(slice(150, 160), slice(220, 230))
    assert part is not None and part.depth.shape == (10, 10)
    assert np.array_equal(part.tile, whole.tile[50:60, 20:30])
    assert whole.within(slice(90, 160), slice(220, 230)) is None
    assert whole.within(slice(150, 160), slice(220, 501)) is None


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


def test_a_square_where_a_triangle_was_planned_is_not_shown_in_place_from_afar() -> None:
    """Scored on independent scenes from 2-3 m, a square in triangle 13's place was called present:
    it covers the triangle, so all the triangle's pixels agree, and the few pixels where the two
    differ (its corners, 2 cm above tile 11) voted 0 to 7 and 0 to 17 for the square. A tile that a
    look-alike type explains as well is not shown in place; the triangle in its place still is."""
    paper = structure()
    swapped = Scene(paper, tuple(paper.tile_ids), (), {13: _swapped(13, "square")})
    bearings = (30.0, 90.0, 150.0, 210.0, 270.0, 330.0)
    far = states_from(swapped, 13, bearings, seeds=(31, 32), distance=2.2)
    # before: present from 4 of the 6; the 2 left have no pixel that tells the two types apart
    assert far.count(TileState.PRESENT) <= 2, far
    assert TileState.MISSING not in far
    in_place = states_from(Scene(paper, tuple(paper.tile_ids), ()), 13, bearings, seeds=(31, 32), distance=2.2)
    assert in_place.count(TileState.PRESENT) >= 3, in_place  # before: 4; one held back by a noisy pixel
    assert TileState.MISSING not in in_place
