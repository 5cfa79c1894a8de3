"""Which assembly robots are alive, from their heartbeats (beyond the paper).

The paper assumes robots never die. A robot that stops sending its periodic status for longer
than `timeout` is lost: it is left out of auctions and its tiles are given to the others.
A robot heard again after being lost is alive again (e.g. after a restart).
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Liveness:
    timeout: float  # s without a heartbeat before a robot counts as lost
    last_heard: dict[str, float] = field(default_factory=dict)
    lost: set[str] = field(default_factory=set)

    def heard(self, robot: str, now: float) -> bool:
        """Record a heartbeat; True when the robot was lost and is back."""
        self.last_heard[robot] = now
        if robot in self.lost:
            self.lost.discard(robot)
            return True
        return False

    def newly_lost(self, now: float) -> list[str]:
        """Robots whose heartbeat stopped since the last call."""
        gone = sorted(
            r for r, t in self.last_heard.items() if r not in self.lost and now - t > self.timeout
        )
        self.lost.update(gone)
        return gone

    def alive(self) -> list[str]:
        return sorted(r for r in self.last_heard if r not in self.lost)
