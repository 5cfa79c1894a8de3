"""The world's side of the simulated clock's pace while VI robots wait for their scans (see
`sim_clock`): FAST, unless an explorer stopped for a scan; then STOPPED from the snapshot until
its VI robot's body has rendered and published the frame (a Kinect delivers at once), REAL while
vi_node judges it (the inspection's real cost), FAST again once judged or given up.

Each VI robot holds the clock for its own scan; with several, the slowest hold sets the pace
(stopped before real before fast), as if their inspections ran side by side on their own computers.
A body says how its scan fares (`/sim/scan_progress`); a hold its body never ends (the body died,
its messages were lost) lapses after `limit` s of wall time, so the world's clock never stays
stopped for good.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tiling_sim.sim_clock import Pace


@dataclass
class _Hold:
    stamp_ns: int  # the held scan's stamp
    since: float  # wall time (s) the hold began
    pace: Pace = Pace.STOPPED


@dataclass
class ScanHold:
    limit: float  # s of wall time a hold may last at most
    _holds: dict[str, _Hold] = field(default_factory=dict)  # VI robot -> its held scan

    @property
    def pace(self) -> Pace:
        paces = {hold.pace for hold in self._holds.values()}
        return next((p for p in (Pace.STOPPED, Pace.REAL) if p in paces), Pace.FAST)

    def hold(self, stamp_ns: int, wall: float, robot: str = "") -> None:
        """The snapshot of a scan `robot`'s explorer waits for was taken at `stamp_ns`: time stops."""
        self._holds[robot] = _Hold(stamp_ns, wall)

    def published(self, stamp_ns: int, robot: str = "") -> None:
        """`robot`'s held scan is out: time runs at the wall clock's pace while it is judged."""
        hold = self._holds.get(robot)
        if hold is not None and hold.stamp_ns == stamp_ns and hold.pace is Pace.STOPPED:
            hold.pace = Pace.REAL

    def release(self, stamp_ns: int | None = None, robot: str = "") -> bool:
        """`robot`'s scan of `stamp_ns` (None: whichever is held) was judged or given up; True when
        that ended its hold."""
        hold = self._holds.get(robot)
        if hold is None or (stamp_ns is not None and stamp_ns < hold.stamp_ns):
            return False
        del self._holds[robot]
        return True

    def lapsed(self, wall: float) -> list[str]:
        """The robots whose hold has lasted longer than `limit` at `wall`; their holds end now."""
        over = [robot for robot, hold in self._holds.items() if wall - hold.since > self.limit]
        for robot in over:
            del self._holds[robot]
        return over
