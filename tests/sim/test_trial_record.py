"""The experiment's detection statistics against the world's truth (ROS-free)."""

from __future__ import annotations

from conftest import STRUCTURES

from tiling_assembly.structure_file import load_structure
from tiling_sim.experiment_result import ExperimentConfig, ExperimentResult
from tiling_sim.report import room_wait_lines
from tiling_sim.trial_record import (
    REASON_FOUND_MISSING,
    REASON_MISPLACED,
    REASON_MISSING,
    Announcement,
    RoomWait,
    Scan,
    TrialRecord,
    WorldEvent,
    detection_stats,
    duplicate_placements,
    false_missing_calls,
    false_repairs,
    lost_placements,
    misplacement_outcomes,
    schedule,
)


def record() -> TrialRecord:
    types = {6: "trapezoid", 7: "trapezoid", 8: "square", 9: "square"}
    r = TrialRecord(trial=1, seed=1, removals_planned=3, tile_types=types)
    r.events = [WorldEvent(10.0, "placed", t) for t in (6, 7, 8, 9)] + [
        WorldEvent(50.0, "removed", 6),  # found by a robot at 60
        WorldEvent(55.0, "removed", 7),  # found by inspection at 70, back at 100
        WorldEvent(80.0, "removed", 8),  # never found
        WorldEvent(100.0, "placed", 7),
    ]
    r.announcements = [
        Announcement(60.0, 1, 6, REASON_FOUND_MISSING),
        Announcement(70.0, 2, 7, REASON_MISSING),
        Announcement(90.0, 3, 9, REASON_MISSING),  # 9 was there all along: a false call
        Announcement(120.0, 4, 7, REASON_MISSING),  # after 7 came back: another false call
    ]
    r.scans = [
        Scan(56.0, {7: "present", 9: "present"}, fresh=frozenset({7, 9})),  # 7 called present while away
        Scan(57.0, {7: "present", 9: "missing"}, fresh=frozenset()),  # repeats older views: not counted
        Scan(58.0, {9: "missing"}, fresh=frozenset({9})),
        Scan(52.0, {6: "present"}, fresh=frozenset({6})),  # the last word on 6 before a robot found it
        Scan(82.0, {8: "missing"}, fresh=frozenset({8})),
        Scan(85.0, {8: "present"}, fresh=frozenset({8})),  # ... and on 8, never found
    ]
    return r


def test_every_removal_is_detected_found_by_a_robot_or_undetermined() -> None:
    stats = detection_stats(record())
    assert (stats.removed, stats.detected, stats.found_by_robot, stats.undetermined) == (3, 1, 1, 1)
    assert stats.detection_delays == [10.0, 15.0]  # to the first finding, by anyone
    assert stats.by_type == {"trapezoid": [2, 1, 2], "square": [1, 0, 0]}  # removed, said missing, found


def test_the_paper_counts_the_inspections_last_word_on_each_removed_tile() -> None:
    stats = detection_stats(record())
    # 7: inspection's call opened its auction; 6 and 8: last called present
    assert (stats.reported_missing, stats.reported_nothing, stats.left_present) == (1, 0, 2)
    r = TrialRecord(trial=2, seed=2, removals_planned=3, tile_types={1: "a", 2: "a", 3: "a"})
    r.events = [WorldEvent(10.0, "placed", t) for t in (1, 2, 3)] + [
        WorldEvent(20.0, "removed", t) for t in (1, 2, 3)
    ]
    r.announcements = [Announcement(40.0, 1, t, REASON_FOUND_MISSING) for t in (1, 2, 3)]
    r.scans = [
        Scan(25.0, {1: "missing", 2: "misplaced", 3: "occluded"}, fresh=frozenset({1, 2, 3})),
        Scan(30.0, {1: "missing", 2: "misplaced", 3: "present"}, fresh=frozenset({1, 2})),  # 3: a repeat
    ]
    stats = detection_stats(r)
    # 1 said missing though a robot found it first; "misplaced" claims 2 is there; 3 was undetermined
    assert (stats.reported_missing, stats.left_present, stats.reported_nothing) == (1, 1, 1)
    assert (stats.detected, stats.found_by_robot) == (0, 3)


def test_false_calls_count_fresh_judgements_and_auctions_for_tiles_in_place() -> None:
    stats = detection_stats(record())
    assert stats.missing_called_present == 3  # 7, 6 and 8: each called present by some scan
    assert stats.left_present == 2  # 6 and 8: inspection's last word was present (7 it found)
    assert stats.present_called_missing == 2
    assert (stats.present_judgements, stats.present_judged_missing) == (2, 1)
    assert stats.present_tiles_called_missing == 1  # 9, in its one stay in place
    assert false_missing_calls(record()) == [{"t": 90.0, "tile": 9}, {"t": 120.0, "tile": 7}]


def test_a_tile_lying_wrong_called_missing_is_no_false_negative_of_a_present_tile() -> None:
    """A wrong tile smaller than the planned one leaves most of its place empty: called missing, it
    is counted apart (a robot sent to re-place it finds it in the way and has it repaired), and its
    scans are no judgements of a tile lying right."""
    r = TrialRecord(trial=1, seed=1, removals_planned=0)
    r.events = [WorldEvent(10.0, "placed", 11), WorldEvent(10.0, "misplaced", 11, misplacement="wrong_type"),
                WorldEvent(10.0, "placed", 12), WorldEvent(50.0, "taken_off", 11), WorldEvent(70.0, "placed", 11)]
    r.announcements = [Announcement(30.0, 1, 11, REASON_MISSING), Announcement(80.0, 2, 11, REASON_MISSING)]
    r.scans = [Scan(29.0, {11: "missing", 12: "present"}, fresh=frozenset({11, 12})),
               Scan(79.0, {11: "missing"}, fresh=frozenset({11}))]
    stats = detection_stats(r)
    assert (stats.present_called_missing, stats.wrong_called_missing) == (1, 1)  # the call at 80 s: it lay right
    assert (stats.present_judgements, stats.present_judged_missing) == (2, 1)  # 12 at 29 s, 11 at 79 s
    assert false_missing_calls(r) == [{"t": 80.0, "tile": 11}]
    assert false_missing_calls(r, lying_wrong=True) == [{"t": 30.0, "tile": 11}]


def test_a_tile_carried_to_a_place_already_taken_counts_as_a_duplicate_and_an_absent_tile_as_lost() -> None:
    r = record()
    assert duplicate_placements(r) == []
    r.events.append(WorldEvent(130.0, "already_present", 7, robot="robot2"))
    r.events.append(WorldEvent(131.0, "placed", 9, robot="robot1"))  # 9 never left: placed on itself
    assert [(d["tile"], d["kind"]) for d in duplicate_placements(r)] == [(7, "place taken"), (9, "placed twice")]
    assert lost_placements(r) == [6, 8]  # removed and never back; the trial did not complete
    r.completed_at = 140.0
    assert lost_placements(r) == []


def test_percentiles_by_nearest_rank() -> None:
    from tiling_sim.report import percentile

    values = [0.1 * k for k in range(1, 21)]
    assert percentile(values, 50) == values[9] and percentile(values, 95) == values[18]
    assert percentile([], 95) is None


def test_wrong_landings_are_detected_when_their_repair_is_auctioned_and_repaired_when_right_again() -> None:
    r = TrialRecord(trial=1, seed=1, removals_planned=0)
    r.events = [
        WorldEvent(10.0, "placed", 6), WorldEvent(10.0, "misplaced", 6, misplacement="turn"),
        WorldEvent(12.0, "placed", 7), WorldEvent(12.0, "misplaced", 7, misplacement="wrong_type"),
        WorldEvent(40.0, "taken_off", 6),
        WorldEvent(60.0, "placed", 6), WorldEvent(60.0, "misplaced", 6, misplacement="shift"),  # wrong again
        WorldEvent(70.0, "taken_off", 6), WorldEvent(90.0, "placed", 6),
        WorldEvent(95.0, "placed", 8),
        WorldEvent(100.0, "placed", 5), WorldEvent(100.0, "misplaced", 5, misplacement="shift"),
        WorldEvent(110.0, "removed", 5), WorldEvent(150.0, "placed", 5),  # a removal fault took it away
    ]
    r.announcements = [
        Announcement(30.0, 1, 6, REASON_MISPLACED),
        Announcement(65.0, 2, 6, REASON_MISPLACED),
        Announcement(96.0, 3, 8, REASON_MISPLACED),  # 8 lay right: a false repair
        Announcement(97.0, 4, 6, REASON_MISPLACED),  # 6 was right again by then: another
        Announcement(98.0, 5, 9, REASON_MISPLACED),  # 9 was never placed: a repair puts it there, not false
    ]
    r.decisions = ["tile 6 lies wrong (robot1 found it in the way when placing tile 9): repairing it",
                   "auction 1 opened for tile 6 (trapezoid, lying wrong: repair); bidders: robot1",
                   "tile 6 lies wrong (scans from 2 camera positions say misplaced, ...): repairing it",
                   "tile 8 lies wrong (scans from 2 camera positions say misplaced, ...): repairing it"]
    outcomes = [o.as_dict() for o in misplacement_outcomes(r)]
    assert outcomes == [
        {"tile": 6, "kind": "turn", "injected_at": 10.0, "detected_at": 30.0, "repaired_at": 90.0,
         "found_by": "robot", "removed_at": None},
        {"tile": 7, "kind": "wrong_type", "injected_at": 12.0, "detected_at": None, "repaired_at": None,
         "found_by": None, "removed_at": None},
        {"tile": 6, "kind": "shift", "injected_at": 60.0, "detected_at": 65.0, "repaired_at": 90.0,
         "found_by": "inspection", "removed_at": None},
        {"tile": 5, "kind": "shift", "injected_at": 100.0, "detected_at": None, "repaired_at": 150.0,
         "found_by": None, "removed_at": 110.0},
    ]
    assert false_repairs(r) == [{"t": 96.0, "tile": 8}, {"t": 97.0, "tile": 6}]
    assert not r.present_at(6, 50.0, r.presence_intervals())  # taken off ends its stay


def test_waits_for_room_show_in_the_schedule_and_the_summary() -> None:
    r = record()
    r.completed_at = 200.0
    r.room_waits = [RoomWait("robot1", 20.0, 0.0, ("robot2",), forced=False, elsewhere=True),
                    RoomWait("robot2", 30.0, 12.0, ("robot1",), forced=False),
                    RoomWait("robot2", 90.0, 60.0, ("vi",), forced=True)]
    rooms = [i for i in schedule(r) if i.kind == "wait for room"]
    assert [(i.robot, i.start, i.end) for i in rooms] == [("robot2", 30.0, 42.0), ("robot2", 90.0, 150.0)]
    result = ExperimentResult(ExperimentConfig(), load_structure(STRUCTURES / "paper_14.yaml"), [r])
    (line,) = room_wait_lines(result)
    assert line == ("Trial 1: another robot stood where a robot needed to be 3 times: it stopped elsewhere 1 times, "
                    "waited 2 times, 72 s in all (36.0% of the makespan, summed over robots); "
                    "1 went in anyway after waiting their patience")
