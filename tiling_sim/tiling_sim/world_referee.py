"""What physically happens in the simulated world, step by step, and the events that say so.

The assembly robots' bodies ask at three steps of each placement (`/sim/place`): before they set
out (is the tile part of the structure and not yet in place?), when the picking phase ends (does
the tile slip from the gripper?) and when the placing phase ends (the tile goes into S_p if its
supports are there; checked and placed at once, so that two robots never place the same tile and a
removal never slips in between). Tiles are removed at the fault schedule's times. Each answer comes
with the events to publish on `/sim/events`, in the order they happened; the runner reads them.
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
        """The robot's placing phase ended: the tile goes into S_p if it can."""
        check, reason = self.world.check_placement(tile)
        if check is PlaceCheck.OK:
            self.world.place(tile)
        answer = StepAnswer(OUTCOME_OF_CHECK[check], reason, self.world.absent_supports(tile))
        if check is PlaceCheck.OK:
            answer.events.append(_about("placed", tile, robot))
            if self.world.complete() and not self.complete_reported:
                self.complete_reported = True
                answer.events.append(("complete", {"pending_removals": len(self.faults.removal_times)}))
        elif check is PlaceCheck.ALREADY_PRESENT:
            answer.events.append(_about("already_present", tile, robot))
        else:
            answer.events.append(("refused", {"tile": tile, "robot": robot, "reason": reason}))
        return answer

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
