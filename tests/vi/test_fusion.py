"""Fusion of tile evidence across scans (default mode) and the paper's rescan rule (paper mode)."""

from __future__ import annotations

import numpy as np

from tiling_assembly.scan_freshness import RepeatFilter
from vi_node.classify import TileState
from vi_node.evidence import TileEvidence
from vi_node.fusion import TileFusion, fuse_scan
from vi_node.scan_result import ScanResult, TileResult

P, M, O = int(TileState.PRESENT), int(TileState.MISSING), int(TileState.OCCLUDED)  # noqa: E741


def seen(agree: int, through: int, judged: int) -> TileEvidence:
    e = TileEvidence.zeros(1)
    e.agree[0], e.see_through[0], e.judged[0], e.virtual[0] = agree, through, judged, judged
    return e


def test_a_tile_undetermined_in_each_view_is_resolved_by_their_sum() -> None:
    fusion = TileFusion()
    fusion.add([7], seen(6, 0, 40), [O])  # 6 of 40 pixels seen: undetermined
    assert fusion.state_of(7) == TileState.OCCLUDED and fusion.unresolved([7]) == [7]
    fusion.add([7], seen(5, 0, 40), [O])  # and 5 more from elsewhere: 11 agreeing pixels
    assert fusion.state_of(7) == TileState.PRESENT and fusion.unresolved([7]) == []
    assert fusion.tiles[7].scans == 2 and int(fusion.summed([7]).agree[0]) == 11


def test_views_of_a_sliver_do_not_add_up_to_a_view_of_the_tile() -> None:
    """33 scans from one place saw 30 of a triangle's 598 pixels past two robots, all agreeing with
    the octagon lying there instead: summed, they looked like a clear view."""
    fusion = TileFusion()
    sliver = seen(29, 0, 30)
    sliver.judgeable[0] = 598
    for _ in range(33):
        fusion.add([14], sliver, [O])
    assert fusion.state_of(14) == TileState.OCCLUDED
    clear = seen(200, 0, 220)
    clear.judgeable[0] = 598
    fusion.add([14], clear, [P])
    assert fusion.state_of(14) == TileState.PRESENT


def test_a_tile_seen_present_then_missing_is_missing() -> None:
    fusion = TileFusion()
    for _ in range(5):
        fusion.add([3], seen(200, 2, 220), [P])
    fusion.add([3], seen(3, 150, 160), [M])  # removed while building: the new scan counts alone
    assert fusion.state_of(3) == TileState.MISSING
    assert int(fusion.summed([3]).agree[0]) == 3
    fusion.add([3], seen(0, 0, 100), [O])  # then occluded: still missing
    assert fusion.state_of(3) == TileState.MISSING


def test_a_missing_tile_one_view_sees_present_waits_for_a_second_view() -> None:
    """Tiles do not come back by themselves: one view agreeing with a tile fused missing (a
    misaligned scan fit it onto a clutter box) makes it undetermined; a second view decides."""
    fusion = TileFusion()
    fusion.add([3], seen(2, 150, 160), [M])
    fusion.add([3], seen(1, 140, 160), [M])
    fusion.add([3], seen(150, 3, 160), [P])
    assert fusion.state_of(3) == TileState.OCCLUDED
    fusion.add([3], seen(140, 2, 160), [P])
    assert fusion.state_of(3) == TileState.PRESENT
    fusion.add([3], seen(2, 150, 160), [M])  # and gone again: one view says so
    assert fusion.state_of(3) == TileState.MISSING
    fusion.forget([3])  # re-placed (reported): starts afresh, one view decides
    fusion.add([3], seen(150, 3, 160), [P])
    assert fusion.state_of(3) == TileState.PRESENT


def test_a_few_see_through_pixels_make_a_present_tile_undetermined_not_present() -> None:
    fusion = TileFusion()
    for _ in range(5):
        fusion.add([3], seen(200, 2, 220), [P])
    fusion.add([3], seen(0, 5, 160), [O])  # removed, seen from where only 5 of its pixels show
    assert fusion.state_of(3) == TileState.OCCLUDED  # no longer reported present on old evidence
    fusion.add([3], seen(0, 20, 160), [O])  # another glimpse adds up to a decision
    assert fusion.state_of(3) == TileState.MISSING
    fusion.add([3], seen(2, 0, 160), [O])  # two stray pixels are no reason to doubt it
    assert fusion.state_of(3) == TileState.MISSING


def test_a_glimpse_of_a_decided_tile_changes_nothing() -> None:
    fusion = TileFusion()
    for _ in range(5):
        fusion.add([3], seen(200, 2, 220), [P])
    before = fusion.tiles[3]
    fusion.add([3], seen(1, 1, 160), [O])  # two pixels: not even the scan count moves
    assert fusion.tiles[3] is before and fusion.tiles[3].scans == 5
    assert int(fusion.summed([3]).see_through[0]) == 10 and fusion.state_of(3) == TileState.PRESENT
    fusion.add([3], seen(9, 1, 160), [O])  # ten pixels leaning present: added
    assert fusion.tiles[3].scans == 6 and int(fusion.summed([3]).agree[0]) == 1009


def test_a_split_view_leaves_a_present_tile_undetermined_until_a_view_settles_it() -> None:
    fusion = TileFusion()
    for _ in range(5):
        fusion.add([3], seen(200, 2, 220), [P])
    # half its pixels see through (taken away, the rest agreeing by chance, or the view is off):
    # summed with the old views it would still read present, but the old views do not vouch for it
    fusion.add([3], seen(300, 200, 600), [O])
    assert fusion.state_of(3) == TileState.OCCLUDED
    assert int(fusion.summed([3]).agree[0]) == 1300  # the evidence is kept ...
    fusion.add([3], seen(150, 3, 160), [P])  # ... and a clear view settles it
    assert fusion.state_of(3) == TileState.PRESENT
    fusion.add([3], seen(20, 400, 430), [M])  # a clear view the other way: gone
    assert fusion.state_of(3) == TileState.MISSING


def test_replaced_tiles_start_afresh_and_unknown_tiles_are_unknown() -> None:
    fusion = TileFusion()
    fusion.add([1, 2], TileEvidence(*(np.array([100, 2]),) * 6), [P, M])
    fusion.forget([2])
    assert fusion.state_of(2) == TileState.UNKNOWN and fusion.state_of(1) == TileState.PRESENT
    fusion.forget()
    assert fusion.tiles == {} and fusion.scans == 0


def test_a_misplaced_tile_stays_misplaced_until_seen_in_place() -> None:
    fusion = TileFusion()
    fusion.add([4], seen(60, 40, 120), [O], {4: (True, (0.02, 0.0, 0.1), 0.01)})
    assert fusion.state_of(4) == TileState.MISPLACED
    fusion.add([4], seen(30, 30, 80), [O], {4: (False, (0.0, 0.0, 0.0), 0.004)})  # unsure view
    assert fusion.state_of(4) == TileState.MISPLACED and fusion.tiles[4].offset == (0.02, 0.0, 0.1)
    fusion.forget([4])
    fusion.add([4], seen(200, 0, 210), [P], {4: (False, (0.0, 0.0, 0.0), 0.002)})
    assert fusion.state_of(4) == TileState.PRESENT


def test_a_flagged_tile_seen_in_place_once_is_undetermined_until_a_second_view_agrees() -> None:
    """A cap turned 34 degrees, flagged from two bearings, showed nothing of its turn from the third
    (its moved corners behind its neighbour's faces) and was fused present. A tile does not move back
    onto its place by itself: one view of it in place leaves it undetermined, a second decides; a
    view that flags it again in between keeps it misplaced."""
    fusion = TileFusion()
    flag = {8: (True, (0.0, 0.0, 0.59), 0.006)}
    in_place = {8: (False, (0.0, 0.0, 0.0), 0.002)}
    fusion.add([8], seen(60, 40, 120), [O], flag)
    fusion.add([8], seen(70, 30, 120), [O], flag)
    fusion.add([8], seen(200, 0, 210), [P], in_place)
    assert fusion.state_of(8) == TileState.OCCLUDED
    assert fusion.unresolved([8]) == [8]  # the explorer looks again
    fusion.add([8], seen(60, 40, 120), [O], flag)
    assert fusion.state_of(8) == TileState.MISPLACED
    fusion.add([8], seen(200, 0, 210), [P], in_place)
    fusion.add([8], seen(30, 30, 80), [O], {8: (False, (0.0, 0.0, 0.0), 0.004)})  # unsure: still undetermined
    assert fusion.state_of(8) == TileState.OCCLUDED
    fusion.add([8], seen(190, 0, 200), [P], in_place)
    assert fusion.state_of(8) == TileState.PRESENT


def test_a_tile_never_flagged_is_present_from_one_view() -> None:
    fusion = TileFusion()
    fusion.add([8], seen(200, 0, 210), [P], {8: (False, (0.0, 0.0, 0.0), 0.002)})
    assert fusion.state_of(8) == TileState.PRESENT


def test_the_type_found_in_a_tiles_place_stays_with_its_flag_and_goes_with_it() -> None:
    """A scan that tells a triangle in square 10's place names it; later views that only repeat the
    flag keep the name, views that find the tile in place clear both."""
    fusion = TileFusion()

    def scan(state: TileState, flagged: bool, seen_type: str = "") -> ScanResult:
        e = seen(60, 40, 120)
        tile = TileResult(10, state, 60, 120, 0.6, seen_type=seen_type)
        return ScanResult(True, tiles=[tile], tile_ids=(10,), evidence=e, evidence_states=np.array([int(state)]),
                          misplacement={10: (flagged, (0.0, 0.0, 0.0), 0.003)})

    assert fuse_scan(fusion, scan(TileState.MISPLACED, True, "triangle")).by_id()[10].seen_type == "triangle"
    repeat = fuse_scan(fusion, scan(TileState.OCCLUDED, False)).by_id()[10]
    assert repeat.state == TileState.MISPLACED and repeat.seen_type == "triangle"
    for _ in range(2):  # one view in place after a flag is not enough (a tile does not move back itself)
        fusion.add([10], seen(200, 0, 210), [P], {10: (False, (0.0, 0.0, 0.0), 0.002)})
    fused = fusion.tiles[10]
    assert fusion.state_of(10) == TileState.PRESENT and not fused.misplaced and not fused.seen_type


def test_a_flagged_tile_whose_place_a_later_view_sees_empty_is_missing() -> None:
    """A removed trapezoid flagged once (a misaligned view) must not stay "misplaced": a view that
    sees its place empty and finds nothing of it moved nearby makes it missing, and so does one
    that could not judge its placement (no points of it left); a view that flags it keeps it."""
    for judged in ({5: (False, (0.0, 0.0, 0.0), 0.003)}, None):
        fusion = TileFusion()
        fusion.add([5], seen(280, 450, 900), [M], {5: (True, (0.03, 0.01, 0.0), 0.004)})
        assert fusion.state_of(5) == TileState.MISPLACED
        fusion.add([5], seen(2, 600, 700), [M], {5: (True, (0.03, 0.01, 0.0), 0.004)})
        assert fusion.state_of(5) == TileState.MISPLACED
        fusion.add([5], seen(1, 1500, 2200), [M], judged)
        assert fusion.state_of(5) == TileState.MISSING


def test_the_pixels_of_a_view_that_flags_a_tile_count_for_neither_state() -> None:
    """Independent scene: a square swapped for a long rectangle, which covers the square's place.
    The first view flagged it (all 240 of its pixels agreed with the square), the second saw its
    place empty, the third saw 12 pixels that agreed: summed with the flagging view's, present."""
    fusion = TileFusion()
    fusion.add([10], seen(240, 0, 260), [int(TileState.MISPLACED)], {10: (True, (0.0, 0.0, 0.0), 0.004)})
    assert fusion.state_of(10) == TileState.MISPLACED
    fusion.add([10], seen(3, 40, 60), [M], {10: (False, (0.0, 0.0, 0.0), 0.004)})
    assert fusion.state_of(10) == TileState.MISSING
    fusion.add([10], seen(12, 0, 15), [O])
    assert fusion.state_of(10) != TileState.PRESENT
    assert int(fusion.summed([10]).agree[0]) < 240  # the flagging view's pixels are not in the sum


def test_paper_rules_keep_the_latest_resolved_state() -> None:
    fusion = TileFusion(paper_rules=True)
    fusion.add([5], seen(300, 0, 310), [P])
    fusion.add([5], seen(0, 0, 0), [O])  # occluded from the next view: nothing new
    assert fusion.state_of(5) == TileState.PRESENT
    fusion.add([5], seen(20, 0, 310), [M])
    assert fusion.state_of(5) == TileState.MISSING


def test_fuse_scan_turns_a_scan_result_into_fused_tile_results() -> None:
    fusion = TileFusion()

    def scan(agree: list[int], states: list[int]) -> ScanResult:
        e = TileEvidence.zeros(2)
        e.agree[:] = agree
        e.judged[:] = e.virtual[:] = [40, 40]
        tiles = [
            TileResult(t, TileState(s), a, 40, 1.0) for t, s, a in zip((1, 2), states, agree, strict=True)
        ]
        return ScanResult(True, tiles=tiles, tile_ids=(1, 2), evidence=e, evidence_states=np.array(states))

    first = fuse_scan(fusion, scan([6, 30], [O, P]))
    assert first.scan_count == 1 and first.by_id()[1].state == TileState.OCCLUDED
    second = fuse_scan(fusion, scan([6, 30], [O, P]))
    assert second.scan_count == 2
    assert second.by_id()[1].state == TileState.PRESENT and second.by_id()[1].physical == 12
    assert second.by_id()[2].scans == 2
    failed = ScanResult(False, "alignment failed")
    assert fuse_scan(fusion, failed) is failed and fusion.scans == 2


def test_a_flag_repeated_by_a_later_view_is_not_a_new_observation() -> None:
    """One misaligned scan flagged tile 4; later views that do not flag it themselves report it
    misplaced with the flagging scan's counts, so the auction node does not take the repeat for a
    confirmation from another camera position (tiling_assembly.scan_freshness)."""
    fusion, freshness = TileFusion(), RepeatFilter()

    def scan(agree: int, through: int, flagged: bool) -> ScanResult:
        e = seen(agree, through, 120)
        state = TileState.OCCLUDED
        return ScanResult(True, tiles=[TileResult(4, state, agree, 120, 0.5)], tile_ids=(4,), evidence=e,
                          evidence_states=np.array([int(state)]),
                          misplacement={4: (flagged, (0.024, 0.027, 0.0) if flagged else (0.0, 0.0, 0.0), 0.01)})

    def fresh_and_misplaced(result: ScanResult) -> bool:
        tile = result.by_id()[4]
        evidence = {4: (tile.scans, tile.physical, tile.see_through)}
        return bool(freshness.fresh(evidence)) and tile.state == TileState.MISPLACED

    assert fresh_and_misplaced(fuse_scan(fusion, scan(60, 40, flagged=True)))
    repeat = fuse_scan(fusion, scan(50, 30, flagged=False))
    assert repeat.by_id()[4].state == TileState.MISPLACED and not fresh_and_misplaced(repeat)
    assert fresh_and_misplaced(fuse_scan(fusion, scan(55, 35, flagged=True)))  # flagged again: news
