"""A scan classified under two alignments that fit equally well keeps only the states both give."""

from __future__ import annotations

import numpy as np

from vi_node.classify import TileState
from vi_node.evidence import TileEvidence
from vi_node.fusion import TileFusion, fuse_scan
from vi_node.scan_result import ScanResult, TileResult, keep_what_fits_agree_on

P, M, X = TileState.PRESENT, TileState.MISSING, TileState.MISPLACED


def classified(states: list[TileState], agree: list[int]) -> ScanResult:
    evidence = TileEvidence.zeros(len(states))
    evidence.agree[:] = agree
    evidence.judged[:] = evidence.virtual[:] = 100
    tiles = [TileResult(tile_id=k + 1, state=s, physical=a, virtual=100, ratio=1.0) for k, (s, a) in
             enumerate(zip(states, agree, strict=True))]
    return ScanResult(ok=True, tiles=tiles, tile_ids=tuple(range(1, len(states) + 1)), evidence=evidence,
                      evidence_states=np.array([int(s) for s in states]),
                      misplacement={2: (True, (0.03, 0.0, 0.0), 0.01)})


def test_tiles_the_fits_disagree_on_are_undetermined_and_add_no_evidence() -> None:
    first = classified([P, X, M], [90, 60, 0])
    other = classified([P, P, P], [85, 80, 70])
    kept = keep_what_fits_agree_on(first, other, "alignment ambiguous: fits 4 cm / 0 deg apart")
    assert [t.state for t in kept.tiles] == [P, TileState.OCCLUDED, TileState.OCCLUDED]
    assert list(kept.evidence.agree) == [90, 0, 0] and list(kept.evidence.judged) == [100, 0, 0]
    assert kept.misplacement == {} and "2 tiles on which they disagree" in kept.notes[-1]
    assert list(first.evidence.agree) == [90, 60, 0]  # the inputs are left alone
    fused = fuse_scan(TileFusion(), kept)
    assert [t.state for t in fused.tiles][1:] == [TileState.OCCLUDED, TileState.OCCLUDED]


def test_agreeing_fits_and_failed_rivals_change_nothing() -> None:
    first = classified([P, P], [90, 60])
    assert keep_what_fits_agree_on(first, classified([P, P], [70, 50]), "x") is first
    assert keep_what_fits_agree_on(first, ScanResult(ok=False, reason="doubtful"), "x") is first
