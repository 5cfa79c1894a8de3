"""What physically happens in the simulated world, step by step, and the events that say so.

The assembly robots' bodies ask at three steps of each placement (`/sim/place`): before they set
out (is the tile part of the structure and not yet in place?), when the picking phase ends (does
the tile slip from the gripper?) and when the placing phase ends (the tile goes into S_p if its
supports are there; checked and placed at once, so that two robots never place the same tile and a
removal never slips in between). A placement the fault schedule picks lands shifted, turned or as a
tile of the wrong type (`faults.FaultInjector.landing`; a tile with no room to land so lands as
planned). A repair asks at two steps of a removal (`/sim/place` REMOVING and LIFTED): the tile comes
off when it is there with nothing resting on it. Tiles are removed at the fault schedule's times.
Each answer comes with the events to publish on `/sim/events`, in the order they happened; the
runner reads them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from tiling_sim.faults import FaultInjector
from tiling_sim.world import PhysicalWorld, PlaceCheck

Event = tuple[str, dict[str, Any]]  # kind, fields


class Outcome(Enum):
    OK = "ok"
    ALREADY_PRESENT = "already present"
    SUPPORT_MISSING = "support missing"
    UNKNOWN_TILE = "unknown tile"
    DROPPED = "dropped"
    BLOCKED = "blocked by a wrong tile"
    NOT_THERE = "not there"
    TILE_ON_TOP = "tile on top"


OUTCOME_OF_CHECK = {
    PlaceCheck.OK: Outcome.OK, PlaceCheck.ALREADY_PRESENT: Outcome.ALREADY_PRESENT,
    PlaceCheck.SUPPORT_MISSING: Outcome.SUPPORT_MISSING, PlaceCheck.UNKNOWN_TILE: Outcome.UNKNOWN_TILE,
    PlaceCheck.BLOCKED: Outcome.BLOCKED,
}


@dataclass
class StepAnswer:
    outcome: Outcome
    reason: str = ""  # one line when not OK
    absent_supports: list[int] = field(default_factory=list)
    events: list[Event] = field(default_factory=list)
    wrong_tiles: list[int] = field(default_factory=list)  # BLOCKED: the tiles lying wrong in the way
    resting_on_it: list[int] = field(default_factory=list)  # TILE_ON_TOP


class WorldReferee:
    def __init__(self, world: PhysicalWorld, faults: FaultInjector) -> None:
        self.world = world
        self.faults = faults
        self.complete_reported = False

    def starting(self, robot: str, tile: int) -> StepAnswer:
        """A robot sets out to place `tile`."""
        check, reason = self.world.check_placement(tile)
        if check is PlaceCheck.ALREADY_PRESENT:
            return StepAnswer(Outcome.ALREADY_PRESENT, reason, events=[_about("already_present", tile, robot)])
        if check is PlaceCheck.UNKNOWN_TILE:
            return StepAnswer(Outcome.UNKNOWN_TILE, reason)
        # a support missing now may be back by the time the tile is placed: that is checked then
        return StepAnswer(Outcome.OK, events=[_about("place_started", tile, robot)])

    def picked(self, robot: str, tile: int) -> StepAnswer:
        """The robot's picking phase ended."""
        if self.faults.drops():
            reason = f"tile {tile} slipped from {robot}'s gripper"
            return StepAnswer(Outcome.DROPPED, reason, events=[_about("dropped", tile, robot)])
        return StepAnswer(Outcome.OK)

    def placing(self, robot: str, tile: int) -> StepAnswer:
        """The robot's placing phase ended: the tile goes into S_p if it can, as the faults say it lands."""
        check, reason = self.world.check_placement(tile)
        answer = StepAnswer(OUTCOME_OF_CHECK[check], reason, self.world.absent_supports(tile))
        if check is PlaceCheck.OK:
            answer.events += self._land(robot, tile)
        elif check is PlaceCheck.ALREADY_PRESENT:
            answer.events.append(_about("already_present", tile, robot))
        else:
            answer.wrong_tiles = self.world.blocking(tile) if check is PlaceCheck.BLOCKED else []
            answer.events.append(("refused", {"tile": tile, "robot": robot, "reason": reason}))
        return answer

    def _land(self, robot: str, tile: int) -> list[Event]:
        landing = self.faults.landing(self.world.structure, tile)
        if landing is not None and not self.world.room_for(tile, landing):
            landing = None  # no room to land wrong: it slides into place
        self.world.place(tile, landing)
        events = [_about("placed", tile, robot)]
        if landing is not None:
            events.append(("misplaced", {"tile": tile, "robot": robot, "misplacement": landing.kind,
                                         "how": landing.describe()}))
        if self.world.complete() and not self.complete_reported:
            self.complete_reported = True
            events.append(("complete", {"pending_removals": len(self.faults.removal_times)}))
        return events

    def removing(self, robot: str, tile: int) -> StepAnswer:
        """A robot sets out to take `tile` off the structure."""
        refused = self._cannot_take_off(tile)
        if refused is not None:
            return refused
        return StepAnswer(Outcome.OK, events=[_about("removal_started", tile, robot)])

    def lifted(self, robot: str, tile: int) -> StepAnswer:
        """The robot's lifting phase ended: the tile comes off if nothing rests on it."""
        refused = self._cannot_take_off(tile)
        if refused is not None:
            refused.events.append(("refused", {"tile": tile, "robot": robot, "reason": refused.reason}))
            return refused
        wrong = self.world.misplaced.get(tile)
        self.world.remove(tile)
        self.complete_reported = False
        return StepAnswer(Outcome.OK, events=[("taken_off", {"tile": tile, "robot": robot,
                                                              "lay_wrong": wrong.kind if wrong else None})])

    def _cannot_take_off(self, tile: int) -> StepAnswer | None:
        if tile not in self.world.structure.tiles:
            return StepAnswer(Outcome.UNKNOWN_TILE, f"tile {tile} is not part of {self.world.structure.name}")
        if tile not in self.world.present:
            return StepAnswer(Outcome.NOT_THERE, f"tile {tile} is not on the structure: nothing to take off")
        above = self.world.resting_on(tile)
        if above:
            names = ", ".join(str(t) for t in above)
            return StepAnswer(Outcome.TILE_ON_TOP, f"tile {tile} cannot come off: tile {names} rests on it",
                              resting_on_it=above)
        return None

    def remove_due(self, now: float) -> Event | None:
        """The removal due at `now` (s of simulated time), if one is due and a tile can be taken."""
        if not self.faults.due(now):
            return None
        tile = self.faults.choose(self.world.removable())
        if tile is None:
            return None  # nothing to take yet: try again later
        self.faults.removed()
        self.world.remove(tile)
        self.complete_reported = False
        return ("removed", {"tile": tile})


def _about(kind: str, tile: int, robot: str) -> Event:
    return (kind, {"tile": tile, "robot": robot})
