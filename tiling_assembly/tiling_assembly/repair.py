"""The sequence that repairs a wrong tile: the paper's future work (Section VII, "online adaptation
of the assembly strategy in the presence of incorrect tile placements"), on its precedence graph.

A tile found misplaced (shifted or turned) or of the wrong type must come off the structure and the
right tile go in its place. Physics decides the rest: a tile can come off only when nothing rests
on it, and go on only when everything it rests on is there (Section III, the precedence DAG). So
the placed tiles that rest on the wrong tile, directly or through others, come off first, top
down (reverse precedence order), and go back after the right tile, bottom up (precedence order).
Tiles of the plan not yet placed are left to the plan; a tile resting on the wrong tile alongside
other supports comes off too (it cannot stay floating), and its other supports stay.

Ties are broken by layer, then by tile id, so that the same structure always gives the same
sequence. The sequence assumes the tiles taken off are in place themselves: a second wrong tile
among them is found by inspection on its own and repaired by its own sequence afterwards.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass
from enum import Enum

import networkx as nx

from tiling_assembly.structure import Structure


class RepairError(ValueError):
    """A repair that cannot be planned (one line: which tile, and why)."""


class RepairAction(Enum):
    REMOVE = "remove"
    PLACE = "place"


@dataclass(frozen=True)
class RepairStep:
    action: RepairAction
    tile_id: int
    why: str  # a few words for the decision log

    def __str__(self) -> str:
        return f"{self.action.value} {self.tile_id} ({self.why})"


@dataclass(frozen=True)
class RepairPlan:
    """The steps that take the wrong tile off and leave the right one, and everything that rested
    on it, in place."""

    wrong_tile: int
    steps: tuple[RepairStep, ...]

    @property
    def taken_off(self) -> tuple[int, ...]:
        """The correct tiles that come off and go back, top down."""
        return tuple(s.tile_id for s in self.steps if s.action is RepairAction.REMOVE and s.tile_id != self.wrong_tile)

    def __str__(self) -> str:
        return f"repair of tile {self.wrong_tile}: " + ", ".join(str(step) for step in self.steps)


def plan_repair(structure: Structure, wrong_tile: int, placed: Collection[int]) -> RepairPlan:
    """The repair of `wrong_tile`, given the tiles on the structure now (`placed`, S_p)."""
    if wrong_tile not in structure.tiles:
        raise RepairError(f"tile {wrong_tile} is not in structure '{structure.name}'")
    on_structure = set(placed) & set(structure.tiles)
    if wrong_tile not in on_structure:
        raise RepairError(f"tile {wrong_tile} is not on the structure: there is nothing to take off")
    above = nx.descendants(structure.precedence, wrong_tile) & on_structure
    bottom_up = _bottom_up(structure, above)
    steps = [RepairStep(RepairAction.REMOVE, tile, f"rests on tile {wrong_tile}") for tile in reversed(bottom_up)]
    steps.append(RepairStep(RepairAction.REMOVE, wrong_tile, "the wrong tile"))
    steps.append(RepairStep(RepairAction.PLACE, wrong_tile, "the right tile, in place"))
    steps += [RepairStep(RepairAction.PLACE, tile, "back where it was") for tile in bottom_up]
    return RepairPlan(wrong_tile, tuple(steps))


def _bottom_up(structure: Structure, tiles: set[int]) -> list[int]:
    """`tiles` in an order where every tile comes after the tiles it rests on."""
    below = structure.precedence.subgraph(tiles)
    return list(nx.lexicographical_topological_sort(below, key=lambda t: (structure.layers[t], t)))
