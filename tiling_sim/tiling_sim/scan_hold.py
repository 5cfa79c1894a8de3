"""The world's side of the simulated clock's pace while the VI robot waits for a scan (see
`sim_clock`): FAST, unless the explorer stopped for this scan; then STOPPED from the snapshot until
the VI robot's body has rendered and published the frame (a Kinect delivers at once), REAL while
vi_node judges it (the inspection's real cost), FAST again once judged or given up.

The VI robot's body says how its scan fares (`/sim/scan_progress`); a hold its body never ends
(the body died, its messages were lost) lapses after `limit` s of wall time, so the world's clock
never stays stopped for good.
"""

from __future__ import annotations

from dataclasses import dataclass

from tiling_sim.sim_clock import Pace


@dataclass
class ScanHold:
    limit: float  # s of wall time a hold may last at most
    stamp_ns: int | None = None  # the held scan's stamp
    pace: Pace = Pace.FAST
    since: float = 0.0  # wall time (s) the hold began

    def hold(self, stamp_ns: int, wall: float) -> None:
        """The snapshot of a scan the explorer waits for was taken at `stamp_ns`: time stops."""
        self.stamp_ns, self.pace, self.since = stamp_ns, Pace.STOPPED, wall

    def published(self, stamp_ns: int) -> None:
        """The held scan's frame is out: time runs at the wall clock's pace while it is judged."""
        if self.stamp_ns == stamp_ns and self.pace is Pace.STOPPED:
            self.pace = Pace.REAL

    def release(self, stamp_ns: int | None = None) -> bool:
        """The scan of `stamp_ns` (None: whichever is held) was judged or given up; True when that
        ended the hold."""
        if self.stamp_ns is None or (stamp_ns is not None and stamp_ns < self.stamp_ns):
            return False
        self.stamp_ns, self.pace = None, Pace.FAST
        return True

    def lapsed(self, wall: float) -> bool:
        """True (once) when the hold has lasted longer than `limit` and ends now."""
        if self.stamp_ns is None or wall - self.since <= self.limit:
            return False
        return self.release()
