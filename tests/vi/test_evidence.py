"""Per-pixel evidence (default mode): measured against virtual depth, judged relative to the view."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vi_node.classify import TileState
from vi_node.evidence import EvidenceSettings, TileEvidence, decide, depth_tolerance, interior, pixel_evidence
from vi_node.raycast import FLOOR, VirtualScan

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
