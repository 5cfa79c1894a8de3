"""A scan several alignments explain equally well: only the verdicts they all share are kept."""

from __future__ import annotations

import numpy as np

from vi_node.classify import TileState
from vi_node.evidence import EvidenceSettings, TileEvidence, decide
from vi_node.rival_fits import agreed, distinct, untold
from vi_node.scan_result import ScanResult, TileResult


def pose(x: float, yaw_deg: float = 0.0) -> np.ndarray:
    c, s = np.cos(np.radians(yaw_deg)), np.sin(np.radians(yaw_deg))
    out = np.eye(4)
    out[:2, :2] = [[c, -s], [s, c]]
    out[0, 3] = x
    return out


def result(x: float, counts: list[tuple[int, int, int]], moved: dict[int, bool] | None = None) -> ScanResult:
    """An aligned scan at x with (agree, see_through, judged) per tile 1, 2, 3..."""
    agree = np.array([c[0] for c in counts])
    through = np.array([c[1] for c in counts])
    judged = np.array([c[2] for c in counts])
    zeros = np.zeros(len(counts), dtype=np.int64)
    evidence = TileEvidence(agree, through, zeros, zeros, judged, judged)
    states = decide(evidence, EvidenceSettings())
    tiles = [
        TileResult(tile_id=k + 1, state=TileState(int(states[k])), physical=int(agree[k]), virtual=int(judged[k]),
                   ratio=0.0, see_through=int(through[k]), judged=int(judged[k]))
        for k in range(len(counts))
    ]
    return ScanResult(
        ok=True, tiles=tiles, camera_pose=pose(x), tile_ids=tuple(range(1, len(counts) + 1)), evidence=evidence,
        evidence_states=states,
        misplacement={tile: (flag, (0.03, 0.0, 0.0), 0.01) for tile, flag in (moved or {}).items()},
    )


def test_a_tile_the_rivals_disagree_on_is_undetermined_and_brings_no_evidence():
    present_here = result(0.0, [(200, 5, 210), (180, 0, 190)])
    missing_there = result(0.06, [(190, 10, 210), (10, 170, 190)])
    assert present_here.tiles[1].state == TileState.PRESENT and missing_there.tiles[1].state == TileState.MISSING

    both = agreed([present_here, missing_there])

    assert both.ok and both.rivals == 2
    assert [t.state for t in both.tiles] == [TileState.PRESENT, TileState.OCCLUDED]
    assert both.evidence_states.tolist() == [TileState.PRESENT, TileState.OCCLUDED]
    assert both.evidence.agree.tolist() == [190, 0] and both.evidence.see_through.tolist() == [5, 0]
    assert both.tiles[0].physical == 190 and both.tiles[1].physical == 0 and both.tiles[1].see_through == 0
    assert np.allclose(both.camera_pose, present_here.camera_pose)
    assert "2 fits up to 6 cm" in both.notes[-1] and "1 tile(s)" in both.notes[-1]


def test_a_missing_tile_every_rival_sees_stays_missing_on_the_least_evidence():
    one = result(0.0, [(5, 150, 160)])
    other = result(0.05, [(12, 120, 160)])

    both = agreed([one, other])

    assert both.tiles[0].state == TileState.MISSING
    assert both.evidence.agree.tolist() == [5] and both.evidence.see_through.tolist() == [120]
    assert decide(both.evidence, EvidenceSettings()).tolist() == [TileState.MISSING]


def test_a_misplacement_one_rival_explains_away_is_dropped():
    one = result(0.0, [(100, 0, 100), (100, 0, 100)], moved={1: True, 2: True})
    other = result(0.05, [(100, 0, 100), (100, 0, 100)], moved={1: True, 2: False})

    assert agreed([one, other]).moved_tiles() == [1]


def test_rivals_that_ended_at_one_pose_count_once_and_failed_ones_not_at_all():
    best = result(0.0, [(100, 0, 100)])
    same_place = result(0.01, [(0, 100, 100)])
    failed = ScanResult(ok=False, reason="alignment failed: beyond belief")
    elsewhere = result(0.04, [(90, 0, 100)])

    kept = distinct([failed, best, same_place, elsewhere])

    assert kept == [best, elsewhere]
    assert agreed(kept[:1]) is best


def test_tiles_left_untold_are_undetermined_with_no_evidence_and_no_placement_verdict():
    """Tile 2 seems moved with only tile 1 in place beside it: both untold; tile 3 keeps everything, so
    fusion over scans neither sums their pixels nor takes a flag or an "in place" from this scan."""
    one = result(0.0, [(200, 5, 210), (150, 20, 190), (120, 0, 130)], moved={1: False, 2: True, 3: False})
    told = untold(one, [2, 1], "tile 2 seems moved")
    assert [t.state for t in told.tiles] == [TileState.OCCLUDED, TileState.OCCLUDED, TileState.PRESENT]
    assert told.evidence_states.tolist() == [TileState.OCCLUDED, TileState.OCCLUDED, TileState.PRESENT]
    assert told.evidence.agree.tolist() == [0, 0, 120] and told.evidence.see_through.tolist() == [0, 0, 0]
    assert told.evidence.judged.tolist() == [210, 190, 130]  # how much of it was in view still counts
    assert told.tiles[1].offset == (0.0, 0.0, 0.0) and told.tiles[2].physical == 120
    assert set(told.misplacement) == {3} and told.notes[-1] == "tile 2 seems moved"
    assert [t.state for t in one.tiles] == [TileState.PRESENT, TileState.PRESENT, TileState.PRESENT]  # not changed
