"""Detecting missing tiles from the state and sensing vectors (paper section 2.3).

"The VI-robot monitors these messages to maintain a state vector q, where q_i is 1 if the block
has been placed and 0 otherwise. After each placement, the VI-robot reports a sensing vector q^s,
where q^s_i is 1 if the block is definitely present, -1 if it is missing, and 0 if the presence
or absence of the block cannot be determined. Then, if q_i * q^s_i = -1, a block that a robot
claims to have placed is determined to be missing."

`confirmations` > 1 asks for that many missing observations, with no present one between them,
first (the paper acts on one: a single wrong scan then sends a robot to re-place a tile that is
there), taken from camera positions at least `min_view_change` apart: scans from one standpoint
share their errors (a repetitive structure can be aligned one tile pitch off, and every scan
from there then sees through a whole row). A tile found missing is no longer placed (q_i = 0)
until a robot reports it placed again, and its old sensing value is forgotten then, so a stale -1
cannot flag the new tile. A scan taken before a tile's placement says nothing about it (scans
arrive after some processing time, possibly after the report of a placement they did not see).

Beyond the paper, a robot refused a placement because a support is not physically there is a
second sensor: that support is missing too, without waiting for the VI robot to look.

Beyond the paper too (its future work): a placed tile that scans call MISPLACED (seen, but off its
planned pose, or of another shape) is confirmed as a missing one is, by `confirmations` scans from
camera positions `min_view_change` apart with no present verdict between them (`flagged`), and then
goes to repair. The confirming scans must also agree on how it lies (`Misfit.agrees_with`): a tile
really off its pose is off by the same motion from every side, or holds the same wrong type, while a
fit to noise moves with the view (a pier block in place 3 m off, fitted "shifted 2.5 cm" from one
camera position and otherwise from another, was taken off and put back where it was).

A tile with a wrong tile on it (resting on it, directly or through others) cannot be judged: the
wrong tile's faces, where the plan has none, look like its own moved or gone (a long rectangle's
place holding an octagon made the square under its end look turned 33 degrees). Its verdicts
neither confirm nor clear until that tile is placed right again, or taken off; nor while a tile on
it is suspected (called misplaced, not yet confirmed): the one on top is judged first. Nor can a tile
resting on a tile confirmed lying wrong: it lies where the wrong tile holds it, not where the plan
does (a triangle put on an octagon in a long rectangle's place, by a placement under way when the
repair was auctioned, looked missing, and a second robot was sent to place it while the repairing
robot took it off to put it back). The repair takes it off and puts it back, so it waits for that.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

View = tuple[float, float]  # x, y (m) of the camera in the structure's frame


@dataclass(frozen=True)
class Misfit:
    """How one scan found a placed tile lying wrong: its motion from the planned pose (x, y in m, yaw
    in rad), or the type seen in its place."""

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    seen_type: str = ""

    @property
    def specific(self) -> bool:
        """Whether the scan told how the tile lies (a motion or a type)."""
        return bool(self.seen_type) or (self.x, self.y, self.yaw) != (0.0, 0.0, 0.0)

    def agrees_with(self, other: Misfit, shift: float, turn: float) -> bool:
        """Whether two scans saw the same fault: the same wrong type, or motions within `shift` (m)
        and `turn` (rad) of each other. A scan that found the tile off its faces but neither a motion
        nor a type that explains it (a wrong type, seen from where its shape is not told apart) says
        nothing of how it lies and agrees with any."""
        if not (self.specific and other.specific):
            return True
        if self.seen_type or other.seen_type:
            return self.seen_type == other.seen_type
        turned = math.remainder(self.yaw - other.yaw, 2 * math.pi)
        return math.hypot(self.x - other.x, self.y - other.y) <= shift and abs(turned) <= turn


Sighting = tuple[View | None, Misfit | None]  # a camera position, and what it saw (None: not told)

PRESENT = 1
UNDETERMINED = 0
MISSING = -1


@dataclass
class MismatchDetector:
    """The vectors q and q^s over tile ids, and the rule q_i * q^s_i = -1."""

    confirmations: int = 1
    min_view_change: float = 0.0  # m between the camera positions of two confirming scans
    misfit_shift: float = 0.02  # m, two scans calling a tile misplaced agree when their motions are this close ...
    misfit_turn: float = math.radians(10.0)  # rad, ... and their turns
    q: dict[int, int] = field(default_factory=dict)
    q_sensed: dict[int, int] = field(default_factory=dict)
    missing_streak: dict[int, list[Sighting]] = field(default_factory=dict)  # scans that called it missing
    misplaced_streak: dict[int, list[Sighting]] = field(default_factory=dict)  # scans that called it misplaced
    placed_at: dict[int, float] = field(default_factory=dict)  # s, time of the latest placement
    above: Mapping[int, frozenset[int]] = field(default_factory=dict)  # tile -> the tiles resting on it, all
    lying_wrong: set[int] = field(default_factory=set)  # confirmed lying wrong, still on the structure
    deferred: dict[int, int] = field(default_factory=dict)  # tile -> a wrong (or suspect) tile on it, last call

    def placed(self, tile_id: int, at: float = -math.inf) -> None:
        """A robot reported `tile_id` placed at time `at` (s)."""
        self.q[tile_id] = 1
        self.placed_at[tile_id] = at
        self.q_sensed[tile_id] = UNDETERMINED
        self.missing_streak.pop(tile_id, None)
        self.misplaced_streak.pop(tile_id, None)
        self.lying_wrong.discard(tile_id)

    def taken_off(self, tile_id: int) -> None:
        """A robot took `tile_id` off the structure (for a repair): it hides nothing any more."""
        self.unplaced(tile_id)
        self.lying_wrong.discard(tile_id)

    def lies_wrong(self, tile_id: int) -> None:
        """`tile_id` lies wrong (confirmed by scans, or a robot found it in the way): no longer placed
        as planned, and what it rests on cannot be judged until it is placed right or taken off."""
        self.unplaced(tile_id)
        self.lying_wrong.add(tile_id)
        for below in (t for t, on_it in self.above.items() if tile_id in on_it):
            self.missing_streak.pop(below, None)  # seen with the wrong tile on it: no evidence
            self.misplaced_streak.pop(below, None)

    def wrong_on(self, tile_id: int) -> int | None:
        """A tile lying wrong, or suspected to, that rests on `tile_id` (directly or not); None if none."""
        for above in sorted(self.above.get(tile_id, ())):
            if above in self.lying_wrong or self.misplaced_streak.get(above):
                return above
        return None

    def wrong_under(self, tile_id: int) -> int | None:
        """A tile confirmed lying wrong that `tile_id` rests on (directly or not); None if none."""
        return next((below for below in sorted(self.lying_wrong) if tile_id in self.above.get(below, ())), None)

    def unplaced(self, tile_id: int) -> None:
        """`tile_id` is known not to be in the structure as planned (found missing or lying wrong, taken
        off, or given up)."""
        self.q[tile_id] = 0
        self.missing_streak.pop(tile_id, None)
        self.misplaced_streak.pop(tile_id, None)

    def flagged(self, verdicts: Mapping[int, bool | Misfit], at: float = math.inf,
                view: View | None = None) -> list[int]:
        """Take a scan's verdicts on placed tiles (tile id -> False: present; True or how it lies:
        misplaced) taken at `at` from `view`; other verdicts are left out (they neither confirm nor
        clear). A verdict of True agrees with any other.

        Returns the tiles now confirmed lying wrong; they are no longer placed (q_i = 0) until a robot
        reports them placed again.
        """
        found = []
        self.deferred = {}
        # the tiles on top first: a suspect on top defers the verdicts on what it rests on
        for tile_id, misplaced in sorted(verdicts.items(), key=lambda v: len(self.above.get(v[0], ()))):
            if at < self.placed_at.get(tile_id, -math.inf) or self.q.get(tile_id, 0) != 1:
                continue
            if self._defer(tile_id):
                continue
            if misplaced is False:
                self.misplaced_streak.pop(tile_id, None)
            elif self._confirmed(self.misplaced_streak, tile_id, view,
                                 misplaced if isinstance(misplaced, Misfit) else None):
                self.lies_wrong(tile_id)
                found.append(tile_id)
        return sorted(found)

    def _defer(self, tile_id: int) -> bool:
        wrong = self.wrong_on(tile_id)
        if wrong is None:
            wrong = self.wrong_under(tile_id)
        if wrong is not None:
            self.deferred[tile_id] = wrong
        return wrong is not None

    def sensed(self, states: Mapping[int, int], at: float = math.inf, view: View | None = None) -> list[int]:
        """Take the sensing vector of a scan taken at `at` from camera position `view` (tile id -> 1,
        0 or -1).

        Returns the tiles now missing.
        """
        found = []
        self.deferred = {}
        for tile_id, value in states.items():
            if at < self.placed_at.get(tile_id, -math.inf):
                continue  # the scan predates the placement
            if self._defer(tile_id):
                continue
            self.q_sensed[tile_id] = value
            if value == PRESENT:
                self.missing_streak.pop(tile_id, None)  # an undetermined scan neither confirms nor clears
            if value != MISSING:
                continue
            if self.q.get(tile_id, 0) * value != -1:
                continue
            if self._confirmed(self.missing_streak, tile_id, view):
                found.append(tile_id)
        return sorted(found)

    def _confirmed(self, streaks: dict[int, list[Sighting]], tile_id: int, view: View | None,
                   misfit: Misfit | None = None) -> bool:
        """Add the sighting to the tile's streak; True (and the tile no longer placed) once
        `confirmations` sightings from distinct camera positions, this one among them, agree."""
        sightings = streaks.setdefault(tile_id, [])
        agreeing = [(view, misfit)]
        for seen_from, seen in reversed(sightings):
            if self._new_view([v for v, _ in agreeing], seen_from) and self._agree(seen, misfit):
                agreeing.append((seen_from, seen))
        if self._new_view([v for v, _ in sightings], view):
            sightings.append((view, misfit))
        if len(agreeing) < self.confirmations:
            return False
        self.unplaced(tile_id)
        return True

    def _agree(self, first: Misfit | None, second: Misfit | None) -> bool:
        if first is None or second is None:
            return True
        return first.agrees_with(second, self.misfit_shift, self.misfit_turn)

    def _new_view(self, views: list[View | None], view: View | None) -> bool:
        if view is None or self.min_view_change <= 0:
            return True
        return all(v is None or math.dist(v, view) >= self.min_view_change for v in views)

    def found_absent(self, tile_id: int, at: float = math.inf) -> bool:
        """A robot found `tile_id` physically absent at time `at` (s); True when that is news.

        Only a tile claimed placed before `at` can be missing; one already found missing (or never
        placed) is waiting for its replacement, not missing again.
        """
        if self.q.get(tile_id, 0) != 1 or at < self.placed_at.get(tile_id, -math.inf):
            return False
        self.q_sensed[tile_id] = MISSING
        self.unplaced(tile_id)
        return True

    def placed_tiles(self) -> list[int]:
        return sorted(t for t, v in self.q.items() if v == 1)

    def state_of(self, tile_ids: Iterable[int]) -> dict[int, tuple[int, int]]:
        """(q_i, q^s_i) of each tile, for reports."""
        return {t: (self.q.get(t, 0), self.q_sensed.get(t, 0)) for t in tile_ids}


@dataclass
class UnconfirmedReports:
    """Supports robots found absent while only scans decide (`robots_find_missing` false).

    The reporting robot waits for the support to be placed again; if the scans never confirm it
    missing (the VI robot cannot see it, or its scans do not align), nobody would ever replace it
    and the robot would wait forever. After `timeout` s without a decision the report is acted on.
    """

    timeout: float  # s
    pending: dict[int, tuple[float, float, str, int]] = field(default_factory=dict)  # support -> (due, at, robot, tile)

    def report(self, support: int, robot: str, tile_id: int, at: float) -> None:
        """`robot` found `support` absent at time `at` (s) when placing `tile_id` on it."""
        self.pending.setdefault(support, (at + self.timeout, at, robot, tile_id))

    def due(self, now: float) -> list[tuple[int, float, str, int]]:
        """(support, report time, robot, tile) of the reports whose wait is over, oldest first."""
        over = sorted((entry, support) for support, entry in self.pending.items() if entry[0] <= now)
        for _, support in over:
            del self.pending[support]
        return [(support, at, robot, tile) for (_, at, robot, tile), support in over]
