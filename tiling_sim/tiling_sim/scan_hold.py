"""The world's side of the simulated clock while VI robots scan (see `sim_clock`): a scan costs the
same simulated time on a quiet host and on a busy one.

- The frame an explorer stopped for: the clock STOPS from its snapshot until vi_node has judged it
  (or the frame was given up), and then for the explorer's next move: until its base sets off, or a
  decision window (s of wall time) has passed. Rendering, judging and deciding happen on this host;
  on the robots they would take the robot's own computer a fixed time, not this host's load.
- A drive to a viewpoint: the clock does not pass the arrival (and the base settling) until the frame
  the explorer stopped there for is taken.
- Every frame, stopped for or streamed while the base stands: the clock does not pass its stamp plus
  the scan period until the same VI robot's next snapshot, or until its base moves. A vi_node that
  falls behind holds simulated time back instead of missing frames. (Time used to run on at 20x
  while vi_node judged the streamed frames: under a CPU hog 45 of 67 scans of a misplacement run
  went unjudged, and the figures of a run depended on what else the host was doing.)

- The start: the clock stays at its start until every VI robot has set off for its first viewpoint
  (its explorer takes a few seconds of wall time to find the other VI robots before it chooses; a
  first goal that came when a busy host let it would start the VI robot's whole path late).

Each VI robot holds the clock for its own scans; with several, the tightest hold counts. A hold its
body never ends (the body died, its messages were lost) lapses after `limit` s of wall time (a
ceiling: counted from when the clock reached it), so the world's clock never stays stopped for good.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tiling_sim.sim_clock import Pace

CEILING_MARGIN = 1e-6  # s: a body's clock at a ceiling may read a nanosecond short of it (whole ns stamps)


@dataclass
class _Hold:
    stamp_ns: int  # the scan's stamp
    since: float  # wall time (s) the hold began
    stopped: bool  # the clock stands still until the scan is judged
    ceiling: float | None  # s of simulated time the clock may not pass until the next snapshot
    decision_window: float = 0.0  # s of wall time the stop lasts once the scan is judged
    decided_by: float | None = None  # wall time (s) the stop ends, once judged
    reached_at: float | None = None  # wall time (s) the clock was first seen at the ceiling
    arrival: float | None = None  # s: a drive's hold, until the frame taken after this arrival

    def stops(self, wall: float) -> bool:
        return self.stopped and (self.decided_by is None or wall < self.decided_by)


@dataclass
class ScanHold:
    limit: float  # s of wall time a hold may last at most
    _holds: dict[str, _Hold] = field(default_factory=dict)  # VI robot -> its latest scan's hold
    _first_goals: dict[str, float] = field(default_factory=dict)  # VI robot -> wall time (s) it may set off by

    def pace(self, wall: float) -> Pace:
        """The clock's pace at `wall` (s)."""
        held = any(hold.stops(wall) for hold in self._holds.values())
        return Pace.STOPPED if held or any(wall < by for by in self._first_goals.values()) else Pace.FAST

    def stopping(self, wall: float) -> list[str]:
        """The VI robots that stop the clock at `wall` (s): a scan being judged, or a first viewpoint."""
        judging = {robot for robot, hold in self._holds.items() if hold.stops(wall)}
        return sorted(judging | {robot for robot, by in self._first_goals.items() if wall < by})

    def at_ceiling(self, now: float) -> list[str]:
        """The VI robots whose ceiling holds the clock at `now` (s of simulated time)."""
        return sorted(robot for robot, hold in self._holds.items()
                      if hold.ceiling is not None and now >= hold.ceiling - 2 * CEILING_MARGIN)

    def starting(self, robots: list[str], wall: float, patience: float) -> None:
        """Simulated time starts at wall time `wall` (s): it stays there until each of `robots` sets
        off for its first viewpoint, within `patience` s of wall time."""
        for robot in robots:
            self._first_goals[robot] = wall + patience

    def ceiling(self) -> float | None:
        """The simulated time (s) the clock may not pass now; None: it may run."""
        return min((h.ceiling for h in self._holds.values() if h.ceiling is not None), default=None)

    def hold(self, stamp_ns: int, wall: float, robot: str = "", stop: bool = True, period: float = 0.0,
             decision_window: float = 0.0) -> None:
        """`robot`'s camera took a snapshot at `stamp_ns`: time stops when its explorer stopped for it
        (`stop`), until it is judged and `decision_window` s of wall time more (or the base moves); and
        it does not pass the stamp + `period` (s; 0: no limit) until `robot`'s next snapshot. Replaces
        `robot`'s last hold."""
        driving = self._holds.get(robot)
        if driving is not None and driving.arrival is not None and stamp_ns * 1e-9 < driving.arrival:
            return  # a frame asked for before the base set off: the drive's hold stands
        ceiling = stamp_ns * 1e-9 + period + CEILING_MARGIN if period > 0 else None
        self._holds[robot] = _Hold(stamp_ns, wall, stop, ceiling, decision_window)

    def judged(self, stamp_ns: int | None = None, robot: str = "", wall: float = 0.0) -> bool:
        """`robot`'s scan of `stamp_ns` (None: whichever is held) was judged or given up at `wall`: the
        clock runs again, up to the ceiling, once the decision window has passed. True when that
        scan stopped the clock."""
        hold = self._holds.get(robot)
        if hold is None or (stamp_ns is not None and stamp_ns < hold.stamp_ns) or not hold.stopped \
                or hold.decided_by is not None:
            return False
        hold.decided_by = wall + hold.decision_window
        self._end_stop(robot, wall)
        return True

    def _end_stop(self, robot: str, wall: float) -> None:
        """The stop of `robot`'s hold is over at `wall` once decided: it keeps only its ceiling."""
        hold = self._holds[robot]
        if hold.stopped and hold.decided_by is not None and wall >= hold.decided_by:
            hold.stopped = False
            if hold.ceiling is None:
                del self._holds[robot]

    def moved(self, robot: str = "", until: float | None = None) -> None:
        """`robot`'s base sets off: it takes no frames on the way; the clock does not pass `until` (s:
        its arrival, settled; None: no limit) until the frame taken there."""
        self._first_goals.pop(robot, None)
        self._holds.pop(robot, None)
        if until is not None:
            self._holds[robot] = _Hold(0, float("inf"), False, until + CEILING_MARGIN, arrival=until)

    def lapsed(self, wall: float, now: float = 0.0) -> list[str]:
        """The robots whose hold has lasted longer than `limit` at `wall` (a ceiling: since the clock,
        at `now` s, reached it); their holds end now."""
        self._first_goals = {robot: by for robot, by in self._first_goals.items() if wall < by}  # no fault
        for robot in list(self._holds):
            self._end_stop(robot, wall)
        over = []
        for robot, hold in self._holds.items():
            if hold.ceiling is not None and not hold.stopped:
                if now < hold.ceiling - 2 * CEILING_MARGIN:
                    continue
                hold.reached_at = wall if hold.reached_at is None else hold.reached_at
                if wall - hold.reached_at > self.limit:
                    over.append(robot)
            elif wall - hold.since > self.limit:
                over.append(robot)
        for robot in over:
            del self._holds[robot]
        return over
