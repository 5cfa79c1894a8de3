"""The repair sequence of a wrong tile (tiling_assembly.repair): what comes off, in which order,
and that every sequence is one physics allows and ends with the same tiles in place."""

from __future__ import annotations

import random

import pytest
from conftest import STRUCTURES

from tiling_assembly.repair import RepairAction, RepairError, RepairPlan, plan_repair
from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import load_structure

GATE = load_structure(STRUCTURES / "gate_9.yaml")  # 1->3, 2->4, 3+4->5, 5->6,7,8, 8->9
PAPER = load_structure(STRUCTURES / "paper_14.yaml")  # 6 carries 4 and 9; 11 rests on 4 and 9
PYRAMID = load_structure(STRUCTURES / "pyramid_91.yaml")


def sequence(plan: RepairPlan) -> list[str]:
    return [f"{step.action.value} {step.tile_id}" for step in plan.steps]


def check_physics(structure: Structure, plan: RepairPlan, placed: set[int]) -> None:
    """Every step possible where it comes; the same tiles in place at the end."""
    now = set(placed)
    for step in plan.steps:
        if step.action is RepairAction.REMOVE:
            assert step.tile_id in now, f"{step}: not there"
            resting = set(structure.supported_by[step.tile_id]) & now
            assert not resting, f"{step}: {sorted(resting)} still rest on it"
            now.remove(step.tile_id)
        else:
            assert step.tile_id not in now, f"{step}: already there"
            missing = set(structure.supports[step.tile_id]) - now
            assert not missing, f"{step}: its supports {sorted(missing)} are not there"
            now.add(step.tile_id)
    assert now == placed


def test_a_wrong_tile_with_nothing_on_it_is_swapped() -> None:
    plan = plan_repair(GATE, 9, set(GATE.tile_ids))
    assert sequence(plan) == ["remove 9", "place 9"]
    assert plan.taken_off == ()


def test_the_tile_resting_on_a_wrong_tile_comes_off_first_and_goes_back_after() -> None:
    plan = plan_repair(GATE, 8, set(GATE.tile_ids))
    assert sequence(plan) == ["remove 9", "remove 8", "place 8", "place 9"]
    assert plan.taken_off == (9,)
    assert str(plan) == ("repair of tile 8: remove 9 (rests on tile 8), remove 8 (the wrong tile), "
                         "place 8 (the right tile, in place), place 9 (back where it was)")


def test_two_tiles_on_a_wrong_tile_come_off_and_only_the_placed_ones() -> None:
    placed = {1, 2, 3, 6, 7, 4, 9}  # 11, resting on 4 and 9, is not placed yet
    plan = plan_repair(PAPER, 6, placed)
    assert sequence(plan) == ["remove 9", "remove 4", "remove 6", "place 6", "place 4", "place 9"]
    check_physics(PAPER, plan, placed)


def test_a_chain_comes_off_top_down_and_goes_back_bottom_up() -> None:
    plan = plan_repair(GATE, 3, set(GATE.tile_ids))
    assert sequence(plan) == ["remove 9", "remove 8", "remove 7", "remove 6", "remove 5", "remove 3",
                              "place 3", "place 5", "place 6", "place 7", "place 8", "place 9"]
    # 4 holds the beam up beside 3 but rests on nothing of 3's: it stays
    assert 4 not in plan.taken_off
    check_physics(GATE, plan, set(GATE.tile_ids))


def test_a_tile_not_on_the_structure_cannot_be_repaired() -> None:
    with pytest.raises(RepairError, match=r"^tile 9 is not on the structure: there is nothing to take off$"):
        plan_repair(GATE, 9, {1, 2, 3})
    with pytest.raises(RepairError, match=r"^tile 99 is not in structure 'gate_9'$"):
        plan_repair(GATE, 99, set(GATE.tile_ids))


@pytest.mark.parametrize("structure", [GATE, PAPER, PYRAMID], ids=lambda s: s.name)
def test_every_repair_of_every_partly_built_structure_is_physically_possible(structure: Structure) -> None:
    rng = random.Random(5)
    for _ in range(20):
        # a state a build can reach: every placed tile's supports are placed
        order = list(structure.precedence.nodes)
        placed: set[int] = set()
        for tile in sorted(order, key=lambda t: structure.layers[t]):
            if set(structure.supports[tile]) <= placed and rng.random() < 0.7:
                placed.add(tile)
        for wrong in placed:
            check_physics(structure, plan_repair(structure, wrong, placed), placed)


def test_what_rests_on_a_tile_directly_or_through_others() -> None:
    assert PAPER.resting_above[11] == {13}
    assert PAPER.resting_above[9] == {11, 13}
    assert PAPER.resting_above[7] == {5, 8, 10, 12, 14}
    assert PAPER.resting_above[13] == frozenset()
    assert GATE.resting_above[5] == {6, 7, 8, 9}
