"""The world's side of simulated time while an assembly robot's body is late to go on (DESIGN.md
"Simulate": `/clock`; issue: simulated results must not depend on how busy the host is).

A body that starts a phase of a placement tells the world when that phase ends (`/sim/motion`, busy).
The world's clock does not pass that moment until the body has said what it does next: its next
phase, or that it is idle. So a body whose process runs late (a loaded host, a slow round trip to
the world's `/sim/place`) still ends each phase at its time, and the world applies its steps at
that time, as when the world and the bodies were one process; the other robots wait with it, as
they would in the one process.

A hold its body never ends (the body died, its link is down) lapses after `limit` s of wall time:
the world's clock never stays stopped for good, and the body is held again from its next news.
When simulated time starts, every robot holds it for a short while for its first goal (`starting`).
When a robot's goal ends, the clock stays at that moment for a short while even once the robot goes
on (`reacting`): the robots that waited for what it did begin then too, however the host delays
their news (two robots setting off at one moment then ask for room in the team's order).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class _Promise:
    due: float  # s of simulated time at which the body's next news is due
    patience: float | None = None  # s of wall time it may hold (None: the hold's `limit`)
    expected: bool = False  # its lapse is no fault (the start: a robot may have nothing to begin with)
    held_since: float | None = None  # wall time (s) at which the clock reached `due`


TEAM = ""  # the hold of the team's reactions to a goal's end (no robot's name)


@dataclass
class BodyHold:
    limit: float  # s of wall time a body may hold the clock at most
    _promises: dict[str, _Promise] = field(default_factory=dict)

    def busy_until(self, robot: str, due: float) -> None:
        """`robot` started a phase that ends at `due` (s): it will say what it does next then."""
        self._promises[robot] = _Promise(due)

    def starting(self, robots: list[str], at: float, patience: float) -> None:
        """Simulated time starts at `at` (s): every robot may begin its first goal then, within
        `patience` s of wall time (a robot whose first tile waits for supports has none to begin)."""
        for robot in robots:
            self._promises.setdefault(robot, _Promise(at, patience, expected=True))

    def reacting(self, at: float, window: float) -> None:
        """A robot's goal ended at `at` (s): the clock stays there `window` s of wall time for the others."""
        if window > 0:
            self._promises[TEAM] = _Promise(at, window, expected=True)

    def idle(self, robot: str) -> None:
        """`robot` has nothing under way: it holds nothing."""
        self._promises.pop(robot, None)

    def deciding(self, now: float) -> list[str]:
        """The robots whose news of what they do at `now` (s) is still due: the clock waits for them."""
        return [robot for robot, promise in self._promises.items() if promise.due <= now + 1e-9]

    def ceiling(self) -> float | None:
        """The simulated time (s) the clock may not pass now; None: it may run."""
        return min((p.due for p in self._promises.values()), default=None)

    def lapsed(self, now: float, wall: float) -> list[str]:
        """The robots whose hold, reached at simulated time `now`, has lasted longer than `limit` at
        wall time `wall`; their holds end now."""
        gone = []
        for robot, promise in self._promises.items():
            if promise.due > now:
                continue
            if promise.held_since is None:
                promise.held_since = wall
            elif wall - promise.held_since > (self.limit if promise.patience is None else promise.patience):
                gone.append(robot)
        faults = [robot for robot in gone if not self._promises[robot].expected]
        for robot in gone:
            del self._promises[robot]
        return faults
