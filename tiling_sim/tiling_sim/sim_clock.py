"""Simulated time that stays honest when the host is slow (DESIGN.md "Simulate": `/clock`, faster
than real time).

Simulated time runs `factor` times faster than the wall clock, except while a robot waits for work
its own computer would also take real time for, such as the inspection of the scan it stopped to
take: then it runs at the wall clock's pace. Work only the simulation does (rendering that scan,
which a Kinect delivers at once) stops it. Without this, a scan that takes 100 ms to judge would
cost the scanning robot 2 s of simulated time at 20x, and the result of a trial would depend on
how busy the host is.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum


class Pace(Enum):
    FAST = "fast"  # nobody waits for real work: `factor` times the wall clock
    REAL = "real"  # a robot waits for work that takes real time on its own computer
    STOPPED = "stopped"  # a robot waits for work only the simulation does


@dataclass
class SimClock:
    factor: float  # simulated seconds per wall-clock second, when nothing is waited for
    now: float = 0.0  # s of simulated time
    _last_wall: float | None = None

    def start(self, wall: float) -> None:
        """Time runs from now (wall clock `wall`, s)."""
        self._last_wall = wall

    @property
    def running(self) -> bool:
        return self._last_wall is not None

    def advance(self, wall: float, pace: Pace = Pace.FAST, ceiling: float | None = None) -> float:
        """Simulated time at wall clock `wall` (s), having run at `pace` since the last call, but not
        past `ceiling` (s; a body the world waits for, see `body_hold`). Time never runs backwards."""
        if self._last_wall is not None:
            elapsed = max(0.0, wall - self._last_wall)
            rate = {Pace.FAST: self.factor, Pace.REAL: 1.0, Pace.STOPPED: 0.0}[pace]
            ahead = self.now + elapsed * rate
            self.now = ahead if ceiling is None else max(self.now, min(ahead, ceiling))
            self._last_wall = wall
        return self.now
