"""Where an assembly robot waits while it has nothing to place (beyond the paper, section 3.1).

The paper's robots stop beside the structure after placing their last tile, and stay there. There
they stand between the structure and the scanning robot's camera: in a paper_14 misplacement run
two idle robots beside the structure hid all but 30 of a wrong tile's 598 pixels from nearly every
viewpoint, and the wrong tile was never confirmed from a second place, so never repaired. A robot
with nothing left to place therefore drives home: where the overhead cameras first saw it (its
start, as the user set the team up), or a spot the user names. A task it wins later in an auction
starts from there. One drive per idle spell: a drive that fails is not tried again until the robot
has had work again, so a robot that cannot get home does not keep its base busy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Point2 = tuple[float, float]


@dataclass
class Parking:
    """Whether and where a robot should drive to wait out of the way."""

    home: Point2 | None = None  # where to wait; None until known
    tolerance: float = 0.15  # m: this close to home counts as home (the overhead view errs by 5 cm)
    tried: bool = False  # a drive home was started in this idle spell

    def saw_robot_at(self, where: Point2) -> None:
        """The overhead cameras saw the base at `where`: the first sighting is home, unless named."""
        if self.home is None:
            self.home = where

    def drive_home(self, idle: bool, standing_at: Point2 | None) -> Point2 | None:
        """Where to drive now: home when the robot is idle, away from it, and has not tried yet."""
        if not idle:
            self.tried = False
            return None
        if self.tried or self.home is None or standing_at is None:
            return None
        if math.dist(standing_at, self.home) <= self.tolerance:
            return None
        return self.home

    def started(self) -> None:
        """A drive home was sent."""
        self.tried = True


def facing(home: Point2, centre: Point2) -> float:
    """The heading (rad) from `home` towards `centre`: a parked robot faces the work."""
    if math.dist(home, centre) < 1e-9:
        return 0.0
    return math.atan2(centre[1] - home[1], centre[0] - home[0])
