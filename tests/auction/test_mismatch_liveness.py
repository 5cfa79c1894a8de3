"""q * q^s = -1 (paper section 2.3) and heartbeat liveness."""

from __future__ import annotations

import math
from types import SimpleNamespace

from auction_node.liveness import Liveness
from auction_node.mismatch import MISSING, PRESENT, UNDETERMINED, Misfit, MismatchDetector, UnconfirmedReports
from tiling_assembly.scan_freshness import RepeatFilter


def test_only_tiles_claimed_placed_can_be_missing() -> None:
    detector = MismatchDetector()
    detector.placed(4)
    assert detector.sensed({4: MISSING, 5: MISSING, 6: PRESENT}) == [4]
    assert detector.q[4] == 0  # no longer placed: not detected twice
    assert detector.sensed({4: MISSING}) == []


def test_undetermined_and_present_tiles_are_not_missing() -> None:
    detector = MismatchDetector()
    detector.placed(4)
    assert detector.sensed({4: UNDETERMINED}) == []
    assert detector.sensed({4: PRESENT}) == []


def test_replaced_tile_forgets_its_old_sensing() -> None:
    detector = MismatchDetector()
    detector.placed(4)
    assert detector.sensed({4: MISSING}) == [4]
    detector.placed(4)
    assert detector.q_sensed[4] == UNDETERMINED
    assert detector.sensed({4: PRESENT}) == []


def test_a_scan_older_than_the_placement_says_nothing_about_it() -> None:
    detector = MismatchDetector()
    detector.placed(4, at=100.0)
    assert detector.sensed({4: MISSING}, at=98.5) == []  # taken before the tile was there
    assert detector.sensed({4: MISSING}, at=101.0) == [4]


def test_confirmations_need_missing_scans_without_a_present_one_between() -> None:
    detector = MismatchDetector(confirmations=2)
    detector.placed(4)
    assert detector.sensed({4: MISSING}) == []
    assert detector.sensed({4: PRESENT}) == []  # cleared
    assert detector.sensed({4: MISSING}) == []
    assert detector.sensed({4: UNDETERMINED}) == []  # e.g. occluded from the next viewpoint
    assert detector.sensed({4: MISSING}) == [4]


def test_confirming_scans_must_come_from_different_standpoints() -> None:
    detector = MismatchDetector(confirmations=2, min_view_change=0.15)
    detector.placed(4)
    assert detector.sensed({4: MISSING}, view=(1.0, 0.0)) == []
    assert detector.sensed({4: MISSING}, view=(1.05, 0.02)) == []  # same standpoint: same error
    assert detector.sensed({4: MISSING}, view=(0.0, 1.0)) == [4]
    detector.placed(5)
    assert detector.sensed({5: MISSING}, view=(1.0, 0.0)) == []
    assert detector.sensed({5: PRESENT}, view=(0.0, 1.0)) == []  # cleared: start again
    assert detector.sensed({5: MISSING}, view=(0.0, 1.1)) == []


def test_a_robot_finding_a_support_absent_makes_it_missing_once() -> None:
    detector = MismatchDetector(confirmations=2)
    assert not detector.found_absent(4, at=50.0)  # never claimed placed
    detector.placed(4, at=100.0)
    assert not detector.found_absent(4, at=99.0)  # a report from before the placement
    assert detector.found_absent(4, at=120.0)
    assert detector.q[4] == 0 and detector.q_sensed[4] == MISSING
    assert not detector.found_absent(4, at=121.0)  # already waiting for its replacement
    assert detector.sensed({4: MISSING}, at=122.0) == []  # nor found again by the next scans
    assert detector.sensed({4: MISSING}, at=123.0) == []


def test_liveness() -> None:
    live = Liveness(timeout=1.0)
    live.heard("robot1", 0.0)
    live.heard("robot2", 0.0)
    live.heard("robot1", 0.8)
    assert live.newly_lost(1.5) == ["robot2"]
    assert live.newly_lost(1.6) == []  # reported once
    assert live.alive() == ["robot1"]
    assert live.heard("robot2", 2.0) is True
    assert live.alive() == ["robot1", "robot2"]


def test_time_the_monitor_did_not_run_does_not_count_against_the_robots() -> None:
    live = Liveness(timeout=1.0, stall=0.5)
    live.heard("robot1", 0.0)
    live.heard("robot2", 0.0)
    for now in (0.2, 0.4, 0.6):
        assert live.newly_lost(now) == []
    assert live.newly_lost(2.0) == []  # the monitor stalled 1.4 s: its queue may hold their heartbeats
    live.heard("robot1", 2.01)  # ... and so it did for robot1; robot2 is silent
    # robot2 was silent 0.6 s before the stall: lost once 0.4 s more of the monitor's own time pass
    assert [live.newly_lost(t) for t in (2.2, 2.4, 2.6, 2.8)] == [[], [], ["robot2"], []]


def test_repeated_fused_evidence_is_not_a_new_observation() -> None:
    repeats = RepeatFilter()
    assert repeats.fresh({4: (1, 300, 0), 5: (1, 0, 80)}) == {4, 5}
    assert repeats.fresh({4: (2, 610, 0), 5: (1, 0, 80)}) == {4}  # 5 not seen again: its old verdict
    assert repeats.fresh({4: (2, 610, 0), 5: (2, 0, 170)}) == {5}
    seen = SimpleNamespace(tile_id=5, scan_count=3, physical_support=0, see_through_support=260)
    repeated = SimpleNamespace(tile_id=4, scan_count=2, physical_support=610, see_through_support=0)
    assert repeats.fresh_states([seen, repeated]) == {5}


def test_an_unconfirmed_report_is_due_after_the_timeout_once() -> None:
    reports = UnconfirmedReports(timeout=60.0)
    reports.report(3, "robot2", 9, at=100.0)
    reports.report(3, "robot1", 11, at=130.0)  # the first report's wait counts
    reports.report(5, "robot1", 12, at=120.0)
    assert reports.due(159.9) == []
    assert reports.due(160.0) == [(3, 100.0, "robot2", 9)]
    assert reports.due(200.0) == [(5, 120.0, "robot1", 12)]
    assert reports.due(500.0) == []


def test_a_tile_lying_wrong_is_confirmed_from_two_standpoints_with_no_present_verdict_between() -> None:
    detector = MismatchDetector(confirmations=2, min_view_change=0.15)
    assert detector.flagged({4: True}, view=(1.0, 0.0)) == []  # never claimed placed: nothing to repair
    detector.placed(4, at=10.0)
    assert detector.flagged({4: True}, at=5.0, view=(1.0, 0.0)) == []  # before the placement
    assert detector.flagged({4: True}, at=20.0, view=(1.0, 0.0)) == []
    assert detector.flagged({4: True}, at=21.0, view=(1.05, 0.0)) == []  # same standpoint
    assert detector.flagged({4: False}, at=22.0, view=(0.0, 1.0)) == []  # present: cleared
    assert detector.flagged({4: True}, at=23.0, view=(0.0, 1.0)) == []
    assert detector.flagged({4: True}, at=24.0, view=(1.0, 0.0)) == [4]
    assert detector.q[4] == 0  # no longer placed until the repair puts it back
    assert detector.flagged({4: True}, at=25.0, view=(0.0, -1.0)) == []
    detector.placed(4, at=30.0)
    assert detector.flagged({4: True}, at=31.0, view=(0.0, -1.0)) == []  # the old streak is forgotten


def test_scans_confirm_a_misplaced_tile_only_when_they_agree_on_how_it_lies() -> None:
    """A pier block in place 3 m off was fitted 'shifted 2.5 cm' from two camera positions, each its own
    way: a fit to noise moves with the view, a tile really off is off alike from every side."""
    detector = MismatchDetector(confirmations=2, min_view_change=0.15, misfit_shift=0.02,
                                misfit_turn=math.radians(10.0))
    detector.placed(7, at=0.0)
    assert detector.flagged({7: Misfit(0.025, 0.0, 0.0)}, at=1.0, view=(1.0, 0.0)) == []
    assert detector.flagged({7: Misfit(-0.01, 0.022, 0.0)}, at=2.0, view=(0.0, 1.0)) == []  # another motion
    assert detector.flagged({7: Misfit(0.0, 0.0, math.radians(20))}, at=3.0, view=(0.0, -1.0)) == []  # a turn
    assert detector.flagged({7: Misfit(0.0, 0.0, 0.0, "square")}, at=4.0, view=(-1.0, 0.0)) == []  # a type
    assert detector.q[7] == 1
    # the same motion (within 2 cm and 10 degrees) from a fifth standpoint confirms it
    assert detector.flagged({7: Misfit(0.003, 0.028, math.radians(4))}, at=5.0, view=(2.0, 2.0)) == [7]
    # a wrong type needs the same type twice; a turn is compared across the wrap-around
    detector.placed(8, at=0.0)
    assert detector.flagged({8: Misfit(seen_type="square")}, at=1.0, view=(1.0, 0.0)) == []
    assert detector.flagged({8: Misfit(seen_type="triangle")}, at=2.0, view=(0.0, 1.0)) == []
    assert detector.flagged({8: Misfit(seen_type="triangle")}, at=3.0, view=(0.0, -1.0)) == [8]
    detector.placed(9, at=0.0)
    assert detector.flagged({9: Misfit(0.0, 0.0, math.radians(179))}, at=1.0, view=(1.0, 0.0)) == []
    assert detector.flagged({9: Misfit(0.0, 0.0, math.radians(-178))}, at=2.0, view=(0.0, 1.0)) == [9]
    # a scan that found it off its faces but could not tell how it lies agrees with any (an octagon
    # in a long rectangle's place fitted no motion from most views, 'octagon' from one)
    detector.placed(10, at=0.0)
    assert detector.flagged({10: Misfit()}, at=1.0, view=(1.0, 0.0)) == []
    assert detector.flagged({10: Misfit(seen_type="octagon")}, at=2.0, view=(0.0, 1.0)) == [10]


def test_a_tile_under_a_wrong_one_is_judged_only_once_that_one_is_repaired() -> None:
    """paper_14: long rectangle 11 rests on square 9 and octagon 4, triangle 13 on 11. An octagon in
    11's place makes square 9 look turned: the one on top is judged first, and what lies under a
    wrong tile waits for its repair."""
    detector = MismatchDetector(confirmations=2, min_view_change=0.15, above={9: frozenset({11, 13}),
                                                                           4: frozenset({11, 13}),
                                                                           11: frozenset({13})})
    for tile in (4, 9, 11, 13):
        detector.placed(tile, at=0.0)
    # both called misplaced in one scan: 11, on top, starts its streak; 9 waits for it
    assert detector.flagged({9: True, 11: True}, at=10.0, view=(1.0, 0.0)) == []
    assert detector.deferred == {9: 11}
    assert detector.flagged({9: True, 11: True}, at=11.0, view=(0.0, 1.0)) == [11]
    assert detector.misplaced_streak.get(9) is None and 11 in detector.lying_wrong
    # while 11 lies wrong, nothing said of 9 or 4 counts, missing or misplaced, nor clears
    assert detector.flagged({9: True}, at=12.0, view=(-1.0, 0.0)) == []
    assert detector.flagged({9: True}, at=13.0, view=(0.0, -1.0)) == []
    assert detector.sensed({4: MISSING}, at=14.0, view=(-1.0, 0.0)) == []
    assert detector.sensed({4: MISSING}, at=15.0, view=(0.0, -1.0)) == []
    assert detector.q[9] == 1 and detector.q[4] == 1
    # 13 and 11 taken off, the right 11 placed: 9 is judged afresh
    detector.taken_off(13)
    detector.taken_off(11)
    detector.placed(11, at=20.0)
    assert detector.flagged({9: True}, at=21.0, view=(1.0, 0.0)) == []
    assert detector.flagged({9: True}, at=22.0, view=(0.0, 1.0)) == [9]


def test_a_tile_a_robot_found_in_the_way_defers_what_it_rests_on() -> None:
    detector = MismatchDetector(confirmations=1, above={5: frozenset({10})})
    detector.placed(5, at=0.0)
    detector.placed(10, at=0.0)
    detector.lies_wrong(10)  # a robot placing a tile found 10 in the way
    assert detector.sensed({5: MISSING}, at=1.0, view=(1.0, 0.0)) == []
    assert detector.deferred == {5: 10}
    detector.taken_off(10)
    assert detector.sensed({5: MISSING}, at=2.0, view=(1.0, 0.0)) == [5]


def test_a_tile_placed_on_a_wrong_one_after_its_repair_was_auctioned_waits_for_that_repair() -> None:
    """paper_14, seed 13: triangle 13 was being placed on 11 when 11 was confirmed lying wrong (an
    octagon in its place). 13 lies where the octagon holds it: the repair takes it off and puts it
    back, and no scan of it counts until then."""
    detector = MismatchDetector(confirmations=2, min_view_change=0.15, above={11: frozenset({13})})
    detector.placed(11, at=0.0)
    detector.lies_wrong(11)
    detector.placed(13, at=5.0)  # the placement under way lands on the wrong tile
    assert detector.sensed({13: MISSING}, at=6.0, view=(1.0, 0.0)) == []
    assert detector.sensed({13: MISSING}, at=7.0, view=(0.0, 1.0)) == []
    assert detector.flagged({13: True}, at=8.0, view=(-1.0, 0.0)) == []
    assert detector.flagged({13: True}, at=9.0, view=(0.0, -1.0)) == []
    assert detector.deferred == {13: 11} and detector.q[13] == 1
    # the repair: 13 off, 11 off, the right 11 in, 13 back; then 13 is judged as any tile
    detector.taken_off(13)
    detector.taken_off(11)
    detector.placed(11, at=20.0)
    detector.placed(13, at=21.0)
    assert detector.sensed({13: MISSING}, at=22.0, view=(1.0, 0.0)) == []
    assert detector.sensed({13: MISSING}, at=23.0, view=(0.0, 1.0)) == [13]


def test_one_vi_robots_repeats_are_not_fresh_because_another_robots_scans_came_in_between() -> None:
    """Two VI robots on one topic: vi1's view is blocked and it repeats its stale fused "present"
    of a tile while vi2 keeps seeing the tile missing. vi1's repeats are no new observations."""
    repeats = RepeatFilter()
    assert repeats.fresh({3: (4, 6045, 16)}, "vi1") == {3}
    for scans in range(1, 5):
        assert repeats.fresh({3: (scans, 0, 1285 * scans)}, "vi2") == {3}
        assert repeats.fresh({3: (4, 6045, 16)}, "vi1") == set()
