"""Which assembly robots are alive, from their heartbeats (beyond the paper).

The paper assumes robots never die. A robot that stops sending its periodic status for longer
than `timeout` is lost: it is left out of auctions and its tiles are given to the others.
A robot heard again after being lost is alive again (e.g. after a restart).

Time the monitor itself did not run (its process starved of CPU, its checks `stall` s or more
apart) does not count against the robots: their heartbeats of that time may still wait in its
queue (on a 2-core host running 4 robots and 2 VI robots, the auction node declared robot1 lost
and, 80 ms later, back: a replan of 54 tiles each time).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Liveness:
    timeout: float  # s without a heartbeat before a robot counts as lost
    stall: float = 0.5  # s between two checks beyond which the monitor itself stalled
    last_heard: dict[str, float] = field(default_factory=dict)
    lost: set[str] = field(default_factory=set)
    last_check: float | None = None

    def heard(self, robot: str, now: float) -> bool:
        """Record a heartbeat; True when the robot was lost and is back."""
        self.last_heard[robot] = now
        if robot in self.lost:
            self.lost.discard(robot)
            return True
        return False

    def newly_lost(self, now: float) -> list[str]:
        """Robots whose heartbeat stopped since the last call."""
        if self.last_check is not None and now - self.last_check >= self.stall:
            missed = now - self.last_check  # the monitor did not run: nobody could be heard
            self.last_heard = {r: min(t + missed, now) for r, t in self.last_heard.items()}
        self.last_check = now
        gone = sorted(
            r for r, t in self.last_heard.items() if r not in self.lost and now - t > self.timeout
        )
        self.lost.update(gone)
        return gone

    def alive(self) -> list[str]:
        return sorted(r for r in self.last_heard if r not in self.lost)
