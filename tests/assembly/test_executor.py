"""The assembly robot's plan executor (ROS-free)."""

from __future__ import annotations

import pytest
from conftest import STRUCTURES

from assembly_node.executor import Outcome, PlanExecutor, Step, StepKind
from tiling_assembly.structure_file import load_structure

PAPER = load_structure(STRUCTURES / "paper_14.yaml")
ROBOT1 = [3, 6, 4, 9, 11, 13]
ROBOT2 = [7, 5, 8, 10, 12, 14, 1, 2]


def executor(tiles: list[int], strict: bool = False, attempts: int = 3) -> PlanExecutor:
    state = PlanExecutor("robot1", PAPER, max_attempts=attempts, strict_order=strict)
    state.adopt_plan(0, tiles)
    return state


def place(state: PlanExecutor, tile: int) -> None:
    step = state.next_step()
    assert (step.kind, step.tile_id) == (StepKind.PLACE, tile)
    state.start(tile)
    assert state.next_step().kind is StepKind.BUSY
    assert state.finish(tile, True) is Outcome.PLACED


def test_idle_until_a_plan_arrives() -> None:
    state = PlanExecutor("robot1", PAPER)
    assert state.next_step().kind is StepKind.IDLE


def test_places_in_order_and_waits_for_supports_of_other_robots() -> None:
    state = executor(ROBOT1, strict=True)
    place(state, 3)
    place(state, 6)
    step = state.next_step()  # octagon 4 rests on 1, 2 (robot 2's) as well
    assert step.kind is StepKind.WAIT and step.tile_id == 4 and step.waiting_for == (1, 2)
    state.note_placed(1)
    state.note_placed(2)
    place(state, 4)
    place(state, 9)
    place(state, 11)
    place(state, 13)
    assert state.next_step().kind is StepKind.DONE
    assert state.placed_by_me == ROBOT1


def test_never_places_a_tile_before_its_supports() -> None:
    state = executor(ROBOT1)
    place(state, 3)
    place(state, 6)
    place(state, 9)  # 4 waits for robot 2's 1 and 2: the ready square 9 goes first
    step = state.next_step()
    assert step.kind is StepKind.WAIT and step.tile_id == 4 and step.waiting_for == (1, 2)


def test_a_later_ready_tile_goes_first_unless_strict() -> None:
    tiles = [3, 4, 6, 9]  # 4 needs 6, which comes later in this order
    relaxed = executor(tiles)
    place(relaxed, 3)
    for tile in (1, 2):
        relaxed.note_placed(tile)
    assert relaxed.next_step().tile_id == 6  # 4 blocked by 6: take 6 first
    strict = executor(tiles, strict=True)
    place(strict, 3)
    for tile in (1, 2):
        strict.note_placed(tile)
    step = strict.next_step()
    assert step.kind is StepKind.WAIT and step.waiting_for == (6,)


def test_missing_support_blocks_again() -> None:
    state = executor([13])
    state.note_placed(11)
    assert state.next_step().kind is StepKind.PLACE
    state.note_missing(11)
    assert state.next_step().waiting_for == (11,)


def test_failures_are_retried_then_given_up() -> None:
    state = executor([3, 1], attempts=2)
    state.start(3)
    assert state.finish(3, False) is Outcome.RETRY
    assert state.next_step().tile_id == 3  # retried first
    state.start(3)
    assert state.finish(3, False) is Outcome.GAVE_UP
    assert 3 not in state.task()
    assert state.next_step().tile_id == 1


def test_absent_supports_block_the_tile_without_using_up_its_attempts() -> None:
    state = executor([13], attempts=1)
    state.note_placed(11)
    for _ in range(3):  # refused again and again: never given up while its support is absent
        state.start(13)
        assert state.finish(13, False, missing_supports=[11]) is Outcome.BLOCKED
        assert state.task() == [13]
        step = state.next_step()
        assert step.kind is StepKind.WAIT and step.waiting_for == (11,)
        state.note_placed(11)  # 11 replaced
    state.note_placed(11)
    state.start(13)
    assert state.finish(13, False) is Outcome.GAVE_UP  # an ordinary failure still counts


def test_a_refusal_naming_no_support_of_the_tile_is_an_ordinary_failure() -> None:
    state = executor([13], attempts=2)
    state.note_placed(11)
    state.start(13)
    assert state.finish(13, False, missing_supports=[5]) is Outcome.RETRY  # 5 does not carry 13


def test_award_goes_to_the_front_when_another_robot_waits_for_it() -> None:
    state = executor([6, 9])
    for tile in (1, 2, 3):
        state.note_placed(tile)
    state.start(6)  # in flight
    state.note_placed(7)
    # octagon 5 was found missing; robot 2's long rectangle 12 and square 10 wait for it
    assert state.award(5) == 0
    assert state.task() == [6, 5, 9]


def test_award_before_the_first_own_dependent_when_nobody_else_waits() -> None:
    state = PlanExecutor("robot2", PAPER)
    state.adopt_plan(0, [8, 12, 14])
    for tile in (1, 2, 3, 7):
        state.note_placed(tile)
    state.note_placed(10)
    # robot2 owns everything above 5 that is not placed (12, 14): insert before 12
    assert state.award(5) == 1
    assert state.task() == [8, 5, 12, 14]


def test_award_of_a_top_tile_goes_last() -> None:
    state = executor([9, 11])
    assert state.award(14) == 2


def test_new_plan_revision_replaces_the_task_but_not_the_tile_in_flight() -> None:
    state = executor([3, 6, 4])
    state.start(3)
    assert not state.adopt_plan(0, [1])  # same revision: ignored
    assert state.adopt_plan(1, [3, 1, 2])
    assert state.task() == [3, 1, 2]
    assert state.finish(3, True) is Outcome.PLACED
    state.note_placed(1)  # placed by someone else meanwhile
    assert state.task() == [2]


def test_start_refuses_foreign_tiles() -> None:
    state = executor([3])
    with pytest.raises(ValueError):
        state.start(5)


def test_a_repair_takes_off_top_down_then_places_bottom_up_before_the_rest() -> None:
    state = executor([13])
    for tile in (1, 2, 3, 6, 4, 9):
        state.note_placed(tile)
    state.award_repair(6, [9, 4])  # 9 and 4 rest on the wrong tile 6, top down
    assert 6 not in state.placed and 4 not in state.placed and 9 not in state.placed
    for tile in (9, 4, 6):
        step = state.next_step()
        assert (step.kind, step.tile_id) == (StepKind.REMOVE, tile)
        state.start_removal(tile)
        assert state.next_step().kind is StepKind.BUSY and state.task()[0] == 6  # nothing placing
        assert state.finish_removal(tile, True) is Outcome.REMOVED
    for tile in (6, 4, 9):  # the right tile, then the others back
        place(state, tile)
    assert state.remaining == [13]


def test_a_tile_found_resting_on_the_one_to_take_off_comes_off_first_and_goes_back() -> None:
    state = executor([13])
    for tile in (1, 2, 3, 6):
        state.note_placed(tile)
    state.award_repair(6, [])
    state.start_removal(6)
    assert state.finish_removal(6, False, resting_on_it=[9]) is Outcome.RETRY  # 9 was placed since
    assert state.removal_attempts[6] == 0  # not the robot's fault
    assert state.next_step() == Step(StepKind.REMOVE, 9)
    state.start_removal(9)
    state.finish_removal(9, True)
    state.start_removal(6)
    state.finish_removal(6, True)
    assert state.remaining == [6, 9, 13]


def test_a_repair_whose_removals_keep_failing_is_given_up() -> None:
    state = executor([13], attempts=2)
    state.note_placed(6)
    state.award_repair(6, [])
    for expected in (Outcome.RETRY, Outcome.GAVE_UP):
        state.start_removal(6)
        assert state.finish_removal(6, False) is expected
    assert state.to_take_off == [] and state.remaining == [13]


def test_a_tile_blocked_by_a_wrong_tile_waits_for_its_repair_without_using_an_attempt() -> None:
    state = executor([9, 13], attempts=1)
    for tile in (6, 4):
        state.note_placed(tile)
    state.start(9)
    assert state.finish(9, False, wrong_tiles=[6]) is Outcome.WAITS_FOR_REPAIR
    assert state.next_step() == Step(StepKind.WAIT, 9, (6,))
    state.note_missing(6)  # the repair takes it off
    state.note_placed(6)  # ... and places it right
    assert state.next_step() == Step(StepKind.PLACE, 9)
    state.start(9)
    assert state.finish(9, True) is Outcome.PLACED  # its one attempt was still there


def test_a_tile_found_lying_wrong_in_its_own_place_is_placed_right_after_its_repair() -> None:
    state = executor([13])
    for tile in (1, 2, 3, 6, 4, 9, 11):
        state.note_placed(tile)
    state.start(13)  # won after a scan called it missing: it is there, shifted
    assert state.finish(13, False, wrong_tiles=[13]) is Outcome.WAITS_FOR_REPAIR
    state.award_repair(13, [])  # this robot won its repair
    state.start_removal(13)
    state.finish_removal(13, True)
    place(state, 13)
    assert state.next_step().kind is StepKind.DONE and not state.blocked_by


def test_a_repair_won_while_the_tile_is_being_placed_places_it_once() -> None:
    state = executor([13])
    for tile in (1, 2, 3, 6, 4, 9, 11):
        state.note_placed(tile)
    state.start(13)  # won after a scan called it missing: it is there, shifted
    state.award_repair(13, [])  # a robot found it in the way meanwhile; this robot won its repair
    assert state.finish(13, False, wrong_tiles=[13]) is Outcome.WAITS_FOR_REPAIR
    assert state.remaining.count(13) == 1
    state.start_removal(13)
    state.finish_removal(13, True)
    place(state, 13)
    assert state.next_step().kind is StepKind.DONE
