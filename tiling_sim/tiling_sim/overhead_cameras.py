"""Overhead localization of the simulated testbed (paper section 3: "errors below 5 cm and 10 degrees").

The overhead cameras see every robot's base: its true x, y and yaw plus an error that stays the same
while the robot stands still and is drawn anew each time the robot comes to a stop. Every draw comes
from one seeded generator, in the order the robots stop, so a trial is reproducible from its seed.
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

Pose2 = tuple[float, float, float]  # x, y (m), yaw (rad) in map


@dataclass(frozen=True)
class OverheadError:
    """The overhead cameras' error for one robot while it stands still."""

    dx: float = 0.0
    dy: float = 0.0
    dyaw: float = 0.0

    @classmethod
    def draw(cls, rng: random.Random, max_position: float, max_yaw: float) -> OverheadError:
        """Uniform over the disc of radius `max_position` (m) and over +- `max_yaw` (rad)."""
        radius = max_position * math.sqrt(rng.random())
        angle = rng.uniform(0, math.tau)
        return cls(radius * math.cos(angle), radius * math.sin(angle), rng.uniform(-max_yaw, max_yaw))


class OverheadCameras:
    def __init__(self, seed: int, max_position: float, max_yaw: float, robots: list[str]) -> None:
        """`robots`: every robot seen, in the order their first errors are drawn."""
        self.rng = random.Random(seed)
        self.max_position = max_position
        self.max_yaw = max_yaw
        self.errors = {name: self._draw() for name in robots}

    def _draw(self) -> OverheadError:
        return OverheadError.draw(self.rng, self.max_position, self.max_yaw)

    def stopped(self, robot: str) -> None:
        """`robot` came to a stop: the cameras see it anew."""
        self.errors[robot] = self._draw()

    def observe(self, robot: str, pose: Pose2) -> Pose2:
        """What the cameras report for `robot` standing at `pose`."""
        error = self.errors[robot]
        return (pose[0] + error.dx, pose[1] + error.dy, pose[2] + error.dyaw)
