"""Per-pixel evidence (default mode): measured against virtual depth, judged relative to the view."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vi_node.blank_evidence import blank_evidence
from vi_node.camera_model import PinholeCamera
from vi_node.classify import TileState
from vi_node.evidence import (
    EvidenceSettings,
    TileEvidence,
    decide,
    depth_tolerance,
    interior,
    pixel_evidence,
    smooth,
    too_deep,
    unexpected,
)
from vi_node.expected_returns import ReturnExpectation
from vi_node.raycast import FLOOR, SurfaceLayer, VirtualScan

SETTINGS = EvidenceSettings()


def virtual_scan() -> VirtualScan:
    """A 20 x 30 window: tile 0 at 1.0 m (columns 2-13), tile 1 at 1.2 m (columns 16-27), floor around."""
    depth = np.full((20, 30), 1.5, dtype=np.float32)
    tile = np.full((20, 30), FLOOR, dtype=np.int64)
    depth[2:18, 2:14], tile[2:18, 2:14] = 1.0, 0
    depth[2:18, 16:28], tile[2:18, 16:28] = 1.2, 1
    face = np.where(tile >= 0, 0, -1)
    return VirtualScan(slice(0, 20), slice(0, 30), depth, tile, face, np.ones((20, 30), np.float32), (30, 20))


def measured(depth: np.ndarray) -> np.ndarray:
    cloud = np.zeros((*depth.shape, 3), dtype=np.float32)
    cloud[..., 2] = depth
    return cloud


def test_agree_see_through_in_front_and_no_return_are_counted_per_tile() -> None:
    virtual = virtual_scan()
    depth = virtual.depth.copy()
    depth[2:18, 16:22] = 1.35  # behind tile 1's expected surface: see-through
    depth[2:18, 22:25] = 1.05  # in front of it: something else hides it
    depth[2:18, 25:28] = np.nan  # no return
    depth[5, 5] = 1.004  # within the noise of tile 0
    evidence = pixel_evidence(measured(depth), virtual, 2, SETTINGS)
    inner = interior(virtual.tile, virtual.depth)
    assert evidence.virtual.tolist() == [16 * 12, 16 * 12]
    assert evidence.judged.tolist() == [int(inner[:, :15].sum()), int(inner[:, 15:].sum())]
    assert evidence.agree[0] == evidence.judged[0] and evidence.see_through[0] == 0
    assert evidence.agree[1] == 0
    assert evidence.see_through[1] == int(inner[:, 16:22].sum())
    assert evidence.in_front[1] == int(inner[:, 22:25].sum())
    assert evidence.no_return[1] == int(inner[:, 25:28].sum())


def test_a_masked_pixel_counts_only_when_it_sees_through_the_tile() -> None:
    """A robot's pixels: what agrees with a tile or hides it may be the robot's body, but a depth
    measured behind a tile's face (the robot standing behind a removed tile) says the ray went
    through the tile's place."""
    virtual = virtual_scan()
    depth = virtual.depth.copy()
    depth[2:18, 2:8] = 1.4  # behind tile 0: a robot seen through its place
    depth[2:18, 16:28] = 1.2  # on tile 1's face: maybe the robot's
    masked = np.zeros(depth.shape, dtype=bool)
    masked[:, :8] = masked[:, 16:] = True

    evidence = pixel_evidence(measured(depth), virtual, 2, SETTINGS, masked=masked)

    inner = interior(virtual.tile, virtual.depth)
    assert evidence.see_through[0] == int(inner[:, 2:8].sum())
    assert evidence.agree[0] == int(inner[:, 8:14].sum())
    assert evidence.judged[0] == int(inner[:, :15].sum())
    assert evidence.agree[1] == evidence.judged[1] == evidence.see_through[1] == 0


def test_depth_edges_are_not_judged_but_same_depth_neighbours_are() -> None:
    virtual = virtual_scan()
    inner = interior(virtual.tile, virtual.depth)
    assert not inner[2, 5] and not inner[10, 2] and inner[3, 5]  # outline against the floor
    tile = virtual.tile.copy()
    tile[2:18, 8:14] = 1  # two tiles side by side at the same depth: the seam stays judged
    assert interior(tile, virtual.depth)[10, 8] and interior(tile, virtual.depth)[10, 7]


def test_tolerance_follows_the_kinect_noise_and_obliquity() -> None:
    near, far = depth_tolerance(np.array([1.0, 2.0], np.float32), np.ones(2, np.float32), SETTINGS)
    assert 0.008 < near < 0.015 and 0.02 < far < 0.04
    oblique = depth_tolerance(
        np.array([1.0], np.float32), np.array([math.cos(math.radians(75))], np.float32), SETTINGS
    )
    assert oblique[0] > near + 0.01


def evidence(agree: int, through: int, judged: int) -> TileEvidence:
    e = TileEvidence.zeros(1)
    e.agree[0], e.see_through[0], e.judged[0], e.virtual[0] = agree, through, judged, judged
    return e


@pytest.mark.parametrize(
    "agree, through, judged, state",
    [
        (9, 1, 12, TileState.PRESENT),  # a small tile far away: 12 pixels predicted, 10 seen, enough
        (9, 1, 120, TileState.OCCLUDED),  # the same 10 pixels of a tile that should fill 120: undetermined
        (2, 30, 40, TileState.MISSING),
        (15, 15, 40, TileState.OCCLUDED),  # half and half: no decision
        (5, 0, 6, TileState.OCCLUDED),  # too few pixels to say anything
    ],
)
def test_tiles_are_decided_relative_to_what_the_view_predicts(
    agree: int, through: int, judged: int, state: TileState
) -> None:
    assert TileState(int(decide(evidence(agree, through, judged), SETTINGS)[0])) == state


def test_a_sliver_left_between_robots_does_not_vouch_for_a_tile() -> None:
    """Two robots by paper_14 hid all but 30 of the 598 pixels of triangle 14, where an octagon lay
    instead: the octagon agreed with the triangle on 29 of them, and the triangle was called present."""
    sliver = evidence(29, 0, 30)
    sliver.judgeable[0] = 598
    assert TileState(int(decide(sliver, SETTINGS)[0])) == TileState.OCCLUDED
    sliver.judgeable[0] = 150  # a fifth of the tile seen, all of it agreeing: enough
    assert TileState(int(decide(sliver, SETTINGS)[0])) == TileState.PRESENT


def test_nothing_counts_against_a_tile_too_deep_in_the_view_to_tell_it_gone() -> None:
    """A pier block in place 2.9 m off saw past its face on 15 of its 19 decisive pixels: an
    alignment turned 0.7 degrees moves it 1.5 cm there, and a disparity step is 2.4 cm. Beyond 2.6 m
    (the camera resolving 2 cm or worse) its see-through and blank pixels say nothing."""
    assert too_deep(np.array([1.0, 2.0, 2.5, 2.7, 3.0]), SETTINGS).tolist() == [False, False, False, True, True]
    seen = evidence(4, 13, 30)
    seen.blank[0] = 2
    assert TileState(int(decide(seen, SETTINGS)[0])) == TileState.MISSING
    far = seen.unopposed(np.array([True]))
    assert TileState(int(decide(far, SETTINGS)[0])) == TileState.OCCLUDED
    assert far.against.tolist() == [0] and far.agree.tolist() == [4]
    assert seen.unopposed(np.array([False])).against.tolist() == [15]


# -- two hypotheses: "the tile is there" against "the tile is gone" -------------------------------
# A 20 x 40 window: tile 0 fills columns 10-29 at 1.0 m, face-on; the floor around it returns.
CAMERA = PinholeCamera(580.0, 580.0, 20.0, 10.0, 40, 20)
ALL, NONE = np.ones((20, 40), dtype=bool), np.zeros((20, 40), dtype=bool)


def two_layer_scan(behind_depth: float, behind_cos: float, tile_cos: float = 1.0) -> VirtualScan:
    """Tile 0 in front of a surface at `behind_depth` seen with |cos| `behind_cos` (the floor
    around the tile lies there too)."""
    depth = np.full((20, 40), behind_depth, dtype=np.float32)
    tile = np.full((20, 40), FLOOR, dtype=np.int64)
    depth[2:18, 10:30], tile[2:18, 10:30] = 1.0, 0
    cos = np.where(tile == 0, tile_cos, behind_cos).astype(np.float32)
    behind = SurfaceLayer(
        np.full((20, 40), behind_depth, np.float32), tile.copy(), np.full((20, 40), behind_cos, np.float32)
    )
    behind.tile[tile == 0] = FLOOR
    face = np.where(tile >= 0, 0, -1)
    return VirtualScan(slice(0, 20), slice(0, 40), depth, tile, face, cos, (40, 20), behind)


def returns(present: np.ndarray, absent_blank: np.ndarray) -> ReturnExpectation:
    return ReturnExpectation(present, ~present, ~absent_blank, absent_blank)


def judge(virtual: VirtualScan, depth: np.ndarray, expected: ReturnExpectation) -> TileEvidence:
    cloud = measured(depth)
    against = blank_evidence(
        depth, virtual, expected, CAMERA, 0.075, unexpected(cloud, virtual, SETTINGS), smooth(virtual.depth)
    )
    return pixel_evidence(cloud, virtual, 1, SETTINGS, against)


def test_a_blank_only_the_missing_tile_explains_counts_against_it() -> None:
    """A thin top-layer tile removed: the rays through its place end on grazing floor, the Kinect
    returns nothing there, while the tile would have returned: evidence of absence."""
    virtual = two_layer_scan(1.4, behind_cos=0.1)
    depth = virtual.depth.copy()
    depth[2:18, 10:30] = np.nan
    depth[virtual.tile == FLOOR] = np.nan  # the grazing floor returns nothing anywhere ...
    depth[:, :3] = 1.4  # ... but the surfaces around the hole do
    depth[18:, :], depth[:2, :] = 1.4, 1.4
    floor_returns = virtual.tile == FLOOR
    floor_returns[:, 3:] &= False
    evidence = judge(virtual, depth, returns((virtual.tile == 0) | floor_returns | ~np.isnan(depth), virtual.tile == 0))
    assert evidence.blank[0] > 100 and evidence.agree[0] == 0
    assert TileState(int(decide(evidence, SETTINGS)[0])) == TileState.MISSING


def test_the_surface_revealed_within_a_centimetre_decides_nothing() -> None:
    """Behind a removed tile lies another surface 8 mm further along the ray: its measurement fits
    both hypotheses, and counts as ambiguous, not as the tile being there."""
    virtual = two_layer_scan(1.008, behind_cos=1.0)
    depth = virtual.depth.copy()
    depth[2:18, 10:30] = 1.006
    evidence = judge(virtual, depth, returns(ALL, NONE))
    assert evidence.agree[0] == 0 and evidence.ambiguous[0] == evidence.judged[0] > 100
    assert TileState(int(decide(evidence, SETTINGS)[0])) == TileState.OCCLUDED
    # three centimetres behind, the hypotheses part: the same tile present agrees
    virtual = two_layer_scan(1.03, behind_cos=1.0)
    depth = virtual.depth.copy()
    evidence = judge(virtual, depth, returns(ALL, NONE))
    assert evidence.agree[0] == evidence.judged[0]
    assert TileState(int(decide(evidence, SETTINGS)[0])) == TileState.PRESENT


def test_a_blank_from_something_nearer_than_the_camera_s_range_says_nothing() -> None:
    """Something 0.3 m from the camera blanks the tile and all around it: both hypotheses expected
    returns around the tile, so the blank is not the tile's absence."""
    virtual = two_layer_scan(1.4, behind_cos=0.1)
    depth = np.full((20, 40), np.nan, dtype=np.float32)
    depth[:, 36:] = 1.4
    expected = returns(np.ones((20, 40), dtype=bool), virtual.tile == 0)
    evidence = judge(virtual, depth, expected)
    assert evidence.blank[0] == 0 and evidence.no_return[0] == evidence.judged[0]
    assert TileState(int(decide(evidence, SETTINGS)[0])) == TileState.OCCLUDED


def test_a_projector_shadow_on_a_present_tile_says_nothing() -> None:
    """An object 0.6 m from the camera, just right of the tile, hides part of it from the projector
    (7.5 cm to the camera's right): blank pixels left of the object are its shadow."""
    virtual = two_layer_scan(1.4, behind_cos=0.1)
    depth = virtual.depth.copy()
    depth[virtual.tile == FLOOR] = 1.4
    depth[:, 30:34] = 0.6  # the object, in front of the floor at the tile's right
    depth[:, 18:30] = np.nan  # its shadow: 580 * 0.075 * (1/0.6 - 1/1.0) = 29 px wide at most
    expected = returns(np.ones((20, 40), dtype=bool), virtual.tile == 0)
    evidence = judge(virtual, depth, expected)
    assert evidence.blank[0] == 0 and evidence.no_return[0] > 100 and evidence.agree[0] > 50
    assert TileState(int(decide(evidence, SETTINGS)[0])) == TileState.PRESENT


def test_a_present_tile_seen_at_grazing_incidence_is_present() -> None:
    """A top face at 72 degrees: its returns are not sure, its depth noisy; what does return lies
    on the face, well apart from the floor 6 cm further along the ray."""
    virtual = two_layer_scan(1.06, behind_cos=0.3, tile_cos=0.3)
    rng = np.random.default_rng(3)
    depth = virtual.depth + rng.normal(0.0, 0.004, virtual.depth.shape).astype(np.float32)
    depth[rng.random(depth.shape) < 0.3] = np.nan  # grazing dropouts
    evidence = judge(virtual, depth, returns(virtual.tile != 0, NONE))
    assert evidence.blank[0] == 0 and evidence.see_through[0] <= 2
    assert TileState(int(decide(evidence, SETTINGS)[0])) == TileState.PRESENT


def test_blank_neighbours_are_edges_without_numpy_warnings() -> None:
    depth = np.full((6, 6), 1.0, dtype=np.float32)
    depth[:, 3:] = np.inf  # no return on the right half
    with np.errstate(all="raise"):
        inside = smooth(depth)
    assert inside[2, 1] and not inside[2, 2] and not inside[2, 4]
