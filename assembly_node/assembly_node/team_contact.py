"""Whether a robot may start a new tile, judged from the auction node's heartbeat (beyond the paper).

A robot cut off from the team (its WiFi link down) keeps doing what it can on its own, but the
auction node cannot tell a robot out of reach from a dead one: after its liveness timeout it hands
that robot's tiles to the others. So a robot that cannot hear the auction node for `timeout`
finishes the tile in its hands and starts no new one; and when it hears again, it waits while the
team still counts it lost, and until it has adopted the plan revision the auction node knows, so
that it never starts a tile the new plan gave to another robot.

A robot that has never heard an auction node (none runs, e.g. a robot tested on its own) is not
held back.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass


@dataclass
class TeamContact:
    robot_name: str
    timeout: float  # s of wall-clock time without the auction node's heartbeat
    last_heard: float | None = None  # wall time
    counted_lost: bool = False
    plan_in_force: int = 0  # the newest plan revision the auction node has heard

    def heard(self, now: float, plan_revision: int, lost_robots: Iterable[str]) -> None:
        self.last_heard = now
        self.counted_lost = self.robot_name in set(lost_robots)
        self.plan_in_force = max(self.plan_in_force, plan_revision)

    def hold_reason(self, now: float, adopted_revision: int) -> str:
        """Why no new tile may start now; empty when one may."""
        if self.last_heard is None:
            return ""
        silent = now - self.last_heard
        if silent > self.timeout:
            return f"cannot hear the auction node for {silent:.1f} s"
        if self.counted_lost:
            return "the auction node counts this robot lost; waiting until it takes it back"
        if adopted_revision < self.plan_in_force:
            return f"waiting for plan revision {self.plan_in_force} (have {adopted_revision})"
        return ""
