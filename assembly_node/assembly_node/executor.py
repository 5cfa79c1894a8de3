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

Beyond the paper (its future work, repairing wrong placements): a tile found lying wrong in the
way, or under the tile to place, keeps that tile waiting until the wrong one is placed again right.
A repair won in an auction (`award_repair`) takes tiles off first (those resting on the wrong tile,
top down, then the wrong tile, as `tiling_assembly.repair` plans it) and puts the right tile and the
others back before anything else.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from enum import Enum

import networkx as nx

from tiling_assembly.structure import Structure


class StepKind(Enum):
    PLACE = "place"  # start the place action for `tile_id`
    REMOVE = "remove"  # start the remove action for `tile_id` (a repair)
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
    WAITS_FOR_REPAIR = "waits for repair"  # tiles lying wrong are in the way: keep the tile, wait for them
    REMOVED = "removed"  # a repair took the tile off


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
    in_flight: int = 0  # tile of the running place (or remove) action, 0 when none
    removing: bool = False  # the running action takes `in_flight` off
    attempts: dict[int, int] = field(default_factory=dict)
    removal_attempts: dict[int, int] = field(default_factory=dict)
    to_take_off: list[int] = field(default_factory=list)  # a repair's removals, in order
    blocked_by: dict[int, set[int]] = field(default_factory=dict)  # tile -> tiles lying wrong in its way

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
        self._unblock(tile_id)

    def _unblock(self, tile_id: int) -> None:
        """`tile_id` is in place as planned now: nothing waits for its repair any more."""
        for waiting in list(self.blocked_by):
            self.blocked_by[waiting].discard(tile_id)
            if not self.blocked_by[waiting]:
                del self.blocked_by[waiting]

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

    def award_repair(self, tile_id: int, resting_on_it: Sequence[int]) -> None:
        """This robot won the repair of `tile_id`, with `resting_on_it` (top down) on it: take those
        and the wrong tile off, then place the right tile and put the others back, before anything else."""
        for tile in (*resting_on_it, tile_id):
            if tile not in self.to_take_off:
                self.to_take_off.append(tile)
        self.put_back_first([tile_id, *reversed(resting_on_it)])

    def put_back_first(self, tiles: Sequence[int]) -> None:
        """`tiles` (bottom up) come off the structure and go back first, before the rest of the task."""
        self.placed.difference_update(tiles)
        self.remaining = list(tiles) + [t for t in self.remaining if t not in tiles]
        for tile in tiles:
            self.attempts.pop(tile, None)

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
        if self.to_take_off:
            return Step(StepKind.REMOVE, self.to_take_off[0])
        if not self.remaining:
            return Step(StepKind.DONE)
        candidates = self.remaining[:1] if self.strict_order else self.remaining
        for tile_id in candidates:
            if not self.blocking_supports(tile_id) and tile_id not in self.blocked_by:
                return Step(StepKind.PLACE, tile_id)
        first = self.remaining[0]
        waiting_for = self.blocking_supports(first) or tuple(sorted(self.blocked_by.get(first, ())))
        return Step(StepKind.WAIT, first, waiting_for)

    def start(self, tile_id: int) -> None:
        """The place action for `tile_id` was sent."""
        if tile_id not in self.remaining:
            raise ValueError(f"tile {tile_id} is not in {self.robot_name}'s task")
        self.remaining.remove(tile_id)
        self.in_flight = tile_id
        self.attempts[tile_id] = self.attempts.get(tile_id, 0) + 1

    def start_removal(self, tile_id: int) -> None:
        """The remove action for `tile_id`, the first of the repair's removals, was sent."""
        if not self.to_take_off or self.to_take_off[0] != tile_id:
            raise ValueError(f"tile {tile_id} is not the next to take off in {self.robot_name}'s repair")
        self.in_flight = tile_id
        self.removing = True
        self.removal_attempts[tile_id] = self.removal_attempts.get(tile_id, 0) + 1

    def finish_removal(self, tile_id: int, success: bool, resting_on_it: Sequence[int] = ()) -> Outcome:
        """The remove action for `tile_id` ended: removed, to be retried, or given up (the repair is
        dropped; the wrong tile goes back to the team as a tile given up).

        Tiles found resting on it (placed after the repair was planned) come off first and go back after.
        """
        if tile_id != self.in_flight or not self.removing:
            raise ValueError(f"tile {tile_id} is not the one being taken off ({self.in_flight})")
        self.in_flight, self.removing = 0, False
        if success:
            self.to_take_off.remove(tile_id)
            self.placed.discard(tile_id)
            self.blocked_by.pop(tile_id, None)  # it lay wrong in its own place: the place is free now
            self.removal_attempts.pop(tile_id, None)
            return Outcome.REMOVED
        on_top = [t for t in resting_on_it if t not in self.to_take_off]
        if on_top:
            self.to_take_off[:0] = on_top
            position = self.remaining.index(tile_id) + 1 if tile_id in self.remaining else 0
            self.remaining[position:position] = [t for t in reversed(on_top) if t not in self.remaining]
            self.placed.difference_update(on_top)
            self.removal_attempts[tile_id] -= 1
            return Outcome.RETRY
        if self.removal_attempts.get(tile_id, 0) < self.max_attempts:
            return Outcome.RETRY
        self.removal_attempts.pop(tile_id, None)
        repair = set(self.to_take_off)
        self.to_take_off.clear()
        self.remaining = [t for t in self.remaining if t not in repair]
        return Outcome.GAVE_UP

    def finish(
        self, tile_id: int, success: bool, missing_supports: Iterable[int] = (), wrong_tiles: Iterable[int] = ()
    ) -> Outcome:
        """The place action for `tile_id` ended: placed, to be retried, given up, or blocked.

        A placement refused because supports are not physically there, or because tiles lie wrong in
        its way, is not the robot's fault and not the tile's: the tile stays first in the task, the
        attempt does not count, and the robot waits until those tiles are reported placed again.
        """
        if tile_id != self.in_flight or self.removing:
            raise ValueError(f"tile {tile_id} is not the one being placed ({self.in_flight})")
        self.in_flight = 0
        wrong = set(wrong_tiles)
        if not success and wrong:
            self.placed -= wrong
            self.blocked_by[tile_id] = wrong
            self.attempts[tile_id] = self.attempts.get(tile_id, 1) - 1
            self._keep_first(tile_id)
            return Outcome.WAITS_FOR_REPAIR
        if success:
            self.placed.add(tile_id)
            self._unblock(tile_id)
            self.placed_by_me.append(tile_id)
            self.attempts.pop(tile_id, None)
            return Outcome.PLACED
        absent = {s for s in missing_supports if s in self.structure.supports[tile_id]}
        if absent:
            self.placed -= absent
            self.attempts[tile_id] = self.attempts.get(tile_id, 1) - 1
            self._keep_first(tile_id)
            return Outcome.BLOCKED
        if self.attempts.get(tile_id, 0) < self.max_attempts:
            self._keep_first(tile_id)
            return Outcome.RETRY
        self.attempts.pop(tile_id, None)
        return Outcome.GAVE_UP

    def _keep_first(self, tile_id: int) -> None:
        """`tile_id` goes back first in the task, unless it is in it already: a repair won while its
        place action ran has put it where it belongs, and a second entry would place it twice."""
        if tile_id not in self.remaining:
            self.remaining.insert(0, tile_id)

    def task(self) -> list[int]:
        """The tiles still to place, the one under way first."""
        placing = [self.in_flight] if self.in_flight and not self.removing else []
        return placing + list(self.remaining)
