"""Executing one robot's share of the plan (paper sections 2.1 and 2.3).

"Distributed implementation of the plan was achieved by encoding the immediate supports for each
component in the plan to ensure robots wait for the placement of a missing support tile by
another robot before placing their parts" (section 3.1). The executor keeps the robot's task
(tile ids in the planned order) and what the team has placed, and says what to do next: place a
tile whose supports are all placed (and not reported missing), wait, or nothing (done).

By default the robot places the first tile *in its planned order* that is ready; it only deviates
from the order when the next planned tile is blocked and a later one is not (never before that
tile's supports are placed). Tiles won in auctions make this necessary: a strict order can
deadlock two robots each waiting for a tile the other holds further down its list. `strict_order`
restores the paper's behaviour of waiting on the next planned tile.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import Enum

import networkx as nx

from tiling_assembly.structure import Structure


class StepKind(Enum):
    PLACE = "place"  # start the place action for `tile_id`
    WAIT = "wait"  # the next tiles wait for supports (`waiting_for`)
    BUSY = "busy"  # a place action is under way
    DONE = "done"  # nothing left to place
    IDLE = "idle"  # no plan yet


@dataclass(frozen=True)
class Step:
    kind: StepKind
    tile_id: int = 0
    waiting_for: tuple[int, ...] = ()


class Outcome(Enum):
    PLACED = "placed"
    RETRY = "retry"
    GAVE_UP = "gave_up"
    BLOCKED = "blocked"  # supports claimed placed are not there: keep the tile, wait for them


@dataclass
class PlanExecutor:
    """The state of one assembly robot's task; all methods are quick and side-effect free."""

    robot_name: str
    structure: Structure
    max_attempts: int = 3
    strict_order: bool = False
    plan_revision: int = -1
    remaining: list[int] = field(default_factory=list)  # to place, in order
    placed: set[int] = field(default_factory=set)  # placed by anyone, not reported missing
    placed_by_me: list[int] = field(default_factory=list)  # in placement order
    in_flight: int = 0  # tile of the running place action, 0 when none
    attempts: dict[int, int] = field(default_factory=dict)

    def adopt_plan(self, revision: int, tiles: Sequence[int]) -> bool:
        """Take this robot's tiles of plan `revision`; older or repeated revisions are ignored."""
        if revision <= self.plan_revision:
            return False
        self.plan_revision = revision
        self.remaining = [t for t in tiles if t not in self.placed and t != self.in_flight]
        return True

    def note_placed(self, tile_id: int) -> None:
        """Some robot placed `tile_id`."""
        self.placed.add(tile_id)
        if tile_id in self.remaining:  # e.g. reassigned and placed by another robot
            self.remaining.remove(tile_id)

    def note_missing(self, tile_id: int) -> None:
        """`tile_id` was placed but is physically missing: it no longer supports anything."""
        self.placed.discard(tile_id)

    def award(self, tile_id: int) -> int:
        """This robot won `tile_id`: insert it where it is needed first; returns its index.

        Needed by another robot's tile (directly or through other tiles): at the front, so that
        nobody waits long. Otherwise before this robot's first tile that depends on it, and at
        the end when nothing depends on it.
        """
        if tile_id in self.remaining or tile_id == self.in_flight:
            return self.remaining.index(tile_id) if tile_id in self.remaining else -1
        self.placed.discard(tile_id)
        dependents = nx.descendants(self.structure.precedence, tile_id)
        mine = set(self.remaining)
        others_waiting = any(t not in mine and t not in self.placed for t in dependents)
        if others_waiting:
            index = 0
        else:
            index = next((k for k, t in enumerate(self.remaining) if t in dependents), len(self.remaining))
        self.remaining.insert(index, tile_id)
        self.attempts.pop(tile_id, None)
        return index

    def release(self, tile_ids: Iterable[int]) -> None:
        """Drop tiles from the task (reassigned elsewhere)."""
        drop = set(tile_ids)
        self.remaining = [t for t in self.remaining if t not in drop]

    def blocking_supports(self, tile_id: int) -> tuple[int, ...]:
        """Supports of `tile_id` that are not placed (or reported missing)."""
        return tuple(s for s in self.structure.supports[tile_id] if s not in self.placed)

    def next_step(self) -> Step:
        """What to do now."""
        if self.plan_revision < 0 and not self.remaining:
            return Step(StepKind.IDLE)
        if self.in_flight:
            return Step(StepKind.BUSY, self.in_flight)
        if not self.remaining:
            return Step(StepKind.DONE)
        candidates = self.remaining[:1] if self.strict_order else self.remaining
        for tile_id in candidates:
            if not self.blocking_supports(tile_id):
                return Step(StepKind.PLACE, tile_id)
        first = self.remaining[0]
        return Step(StepKind.WAIT, first, self.blocking_supports(first))

    def start(self, tile_id: int) -> None:
        """The place action for `tile_id` was sent."""
        if tile_id not in self.remaining:
            raise ValueError(f"tile {tile_id} is not in {self.robot_name}'s task")
        self.remaining.remove(tile_id)
        self.in_flight = tile_id
        self.attempts[tile_id] = self.attempts.get(tile_id, 0) + 1

    def finish(self, tile_id: int, success: bool, missing_supports: Iterable[int] = ()) -> Outcome:
        """The place action for `tile_id` ended: placed, to be retried, given up, or blocked.

        A placement refused because supports are not physically there is not the robot's fault
        and not the tile's: the tile stays first in the task, the attempt does not count, and the
        robot waits until those supports are reported placed again.
        """
        if tile_id != self.in_flight:
            raise ValueError(f"tile {tile_id} is not the one being placed ({self.in_flight})")
        self.in_flight = 0
        if success:
            self.placed.add(tile_id)
            self.placed_by_me.append(tile_id)
            self.attempts.pop(tile_id, None)
            return Outcome.PLACED
        absent = {s for s in missing_supports if s in self.structure.supports[tile_id]}
        if absent:
            self.placed -= absent
            self.attempts[tile_id] = self.attempts.get(tile_id, 1) - 1
            self.remaining.insert(0, tile_id)
            return Outcome.BLOCKED
        if self.attempts.get(tile_id, 0) < self.max_attempts:
            self.remaining.insert(0, tile_id)
            return Outcome.RETRY
        self.attempts.pop(tile_id, None)
        return Outcome.GAVE_UP

    def task(self) -> list[int]:
        """The tiles still to place, the one under way first."""
        return ([self.in_flight] if self.in_flight else []) + list(self.remaining)
