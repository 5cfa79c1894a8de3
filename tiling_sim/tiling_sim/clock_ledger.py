"""Where the wall time of a simulated run goes (DESIGN.md "Simulate": `/clock`).

The world's clock runs `real_time_factor` times faster than the wall clock only while nobody holds
it (`sim_clock`, `body_hold`, `scan_hold`). On a big team most of the wall time can go to holds: a
VI robot's scan being judged, a robot's body late with its next step, the team reacting to a goal's
end. The ledger charges each stretch of wall time between two ticks to what held the clock during
it, split evenly among the holders, and says every `period` s of wall time how fast simulated time
ran and why not faster: the line a user reads to see what a big run waits for.
"""

from __future__ import annotations

from collections import defaultdict
from dataclasses import dataclass, field

RUNNING = "running"


@dataclass(frozen=True)
class Holder:
    """Who held the clock, and how (`kind`: one of `KINDS`)."""

    kind: str
    name: str = ""


KINDS = {
    "scan": "VI scans being judged",
    "frame": "VI robots' next frames",
    "step": "robots' next steps",
    "reaction": "the team's reaction to a goal's end",
}


@dataclass
class ClockLedger:
    period: float  # s of wall time between two reports
    _seconds: dict[Holder | str, float] = field(default_factory=lambda: defaultdict(float))
    _since: float | None = None  # wall time (s) of the current report's start
    _simulated_since: float = 0.0  # s of simulated time at that start

    def charge(self, wall: float, seconds: float, holders: list[Holder], simulated: float) -> None:
        """`seconds` of wall time up to `wall` (s), during which `holders` held the clock (none: it
        ran); `simulated`: the simulated time (s) at the stretch's start."""
        if self._since is None:
            self._since, self._simulated_since = wall - seconds, simulated
        if not holders:
            self._seconds[RUNNING] += seconds
        for holder in holders:
            self._seconds[holder] += seconds / len(holders)

    def due(self, wall: float) -> bool:
        return self._since is not None and wall - self._since >= self.period

    def report(self, wall: float, simulated: float) -> str:
        """One line on the wall time since the last report (then a new report starts)."""
        since = wall if self._since is None else self._since
        elapsed = max(wall - since, 1e-9)
        ran = simulated - self._simulated_since
        parts = [f"{100 * self._seconds.get(RUNNING, 0.0) / elapsed:.0f}% running"]
        for kind, label in KINDS.items():
            shares = [(s, h.name) for h, s in self._seconds.items() if isinstance(h, Holder) and h.kind == kind]
            shares.sort(key=lambda share: (-share[0], share[1]))  # the biggest first, ties by name
            total = sum(s for s, _ in shares)
            if total <= 0.0:
                continue
            names = ", ".join(f"{name} {100 * s / elapsed:.0f}%" for s, name in shares[:3] if name)
            parts.append(f"{100 * total / elapsed:.0f}% held for {label}" + (f" ({names})" if names else ""))
        line = (f"simulated time ran {ran:.1f} s in the last {elapsed:.0f} s of wall time "
                f"({ran / elapsed:.2f}x): " + "; ".join(parts))
        self._seconds = defaultdict(float)
        self._since, self._simulated_since = wall, simulated
        return line
