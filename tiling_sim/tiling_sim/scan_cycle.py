"""When the simulated Kinect of the VI robot takes its next frame.

While the base stands, a frame every `period` s of simulated time, never before vi_node has
answered the last one (or `verdict_timeout` s of wall time have passed without an answer, a lost
frame or a dead vi_node); the world does not let its clock pass a frame's stamp + `period` until the
next frame's snapshot (see `scan_hold`), so the frames come a period apart however busy the host.
Only while vi_node answers: it is counted on from the start (the experiment starts the clock once
it reads the camera; before, the first frame the explorer stopped for was taken whenever the body
asked for it, and the VI robot's whole path moved with it); after it missed a verdict, frames go out
for whoever views them (`ros2 topic echo`, rviz) without holding the world back, each given up
after `VIEWING_TIMEOUT` s, until it answers one again. After the base arrives at a viewpoint it
waits `settle` s, and the next frame is the one the explorer stopped for: the world holds its clock
for it (see `scan_hold`).

A frame goes through three stages: asked (the world's snapshot is on its way), rendering (in the
body's own thread) and published (vi_node judges it).

The explorer decides where to go next on a frame's verdict, and stamps its goal with that frame's
time (`departure`): the base sets off at that frame's time when the explorer stopped for it (the
world's clock stood still there while it was judged), and a period later for a frame streamed while
the base stood, when the next frame is due, which the world's clock cannot pass before the verdict.
So the base leaves at the same simulated time on a quiet host and on a busy one, however long the
verdict took (it used to leave when the goal came: anywhere within the period, by the load).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from tiling_sim.sim_interface import VI_SETTLE

VIEWING_TIMEOUT = 3.0  # s of wall time a frame waits for a verdict while vi_node does not answer
REMEMBERED_FRAMES = 8  # the latest frames whose stamps a goal may name


@dataclass
class Frame:
    held: bool  # the explorer stopped for this frame: the world holds its clock
    asked_wall: float  # s, wall clock
    stamp_ns: int = 0  # the world's time it shows, once the snapshot arrived
    published_wall: float | None = None


@dataclass
class ScanCycle:
    period: float  # s of simulated time between frames while the base stands
    verdict_timeout: float  # s of wall time a frame waits for its snapshot, or for its verdict
    settle: float = VI_SETTLE  # s of simulated time after an arrival before the first frame
    next_at: float = 0.0  # s of simulated time of the next frame
    moving: bool = False
    arrival_due: bool = False  # the next frame is the one the explorer stopped for
    frame: Frame | None = None  # the frame in its stages, if any
    answering: bool = True  # vi_node has missed no verdict (or judged one since): the world waits for it
    taken: dict[int, bool] = field(default_factory=dict)  # stamp (ns) -> held, of the latest frames

    def __post_init__(self) -> None:
        self.next_at = self.next_at or self.period

    def departed(self) -> None:
        """The base sets off: a frame under way shows the place it left, and the frame the explorer
        stops for next must not wait for its verdict."""
        self.moving = True
        self.frame = None

    def arrived(self, now: float) -> None:
        self.moving = False
        self.next_at = now + self.settle
        self.arrival_due = True

    def departure(self, decided_ns: int, now: float) -> float:
        """When the base sets off (s of simulated time) for a goal decided on the verdict of the frame
        stamped `decided_ns`, at `now`: that frame's time when the explorer stopped for it, a period
        later when it was streamed; `now` for a goal stamped otherwise (decided on the explorer's own
        timer, or by someone else) or one that names a time two periods or more from now."""
        held = self.taken.get(decided_ns)
        if held is None:
            return now
        at = decided_ns * 1e-9 + (0.0 if held else self.period)
        return at if abs(at - now) < 2 * self.period else now

    def start(self, now: float, wall: float) -> Frame | None:
        """A new frame when one is due at `now` (simulated s); None otherwise."""
        if self.moving or self.frame is not None or now < self.next_at - 1e-9:
            return None
        self.next_at = now + self.period
        self.frame = Frame(held=self.arrival_due, asked_wall=wall)
        self.arrival_due = False
        return self.frame

    def snapshot_arrived(self, frame: Frame, stamp_ns: int) -> bool:
        """The world's snapshot for `frame` arrived; False when the frame was given up meanwhile."""
        if self.frame is not frame:
            return False
        frame.stamp_ns = stamp_ns
        self.taken[stamp_ns] = frame.held
        while len(self.taken) > REMEMBERED_FRAMES:
            del self.taken[next(iter(self.taken))]
        # a period after the world's time, not this body's (which lags): the world holds its clock there
        self.next_at = stamp_ns * 1e-9 + self.period
        return True

    def published(self, frame: Frame, wall: float) -> None:
        if self.frame is frame:
            frame.published_wall = wall

    def judged(self, stamp_ns: int, wall: float) -> tuple[Frame, float] | None:
        """vi_node answered a scan of `stamp_ns`: the published frame it ends and the wall delay
        since it was published, or None when it is about an older frame."""
        frame = self.frame
        if frame is None or frame.published_wall is None or stamp_ns < frame.stamp_ns:
            return None
        self.frame = None
        self.answering = True
        return frame, wall - frame.published_wall

    def overdue(self, wall: float) -> Frame | None:
        """The frame given up at `wall`: its snapshot or its verdict did not come in time."""
        frame = self.frame
        if frame is None:
            return None
        timeout = self.verdict_timeout if self.answering else min(self.verdict_timeout, VIEWING_TIMEOUT)
        if frame.published_wall is not None:
            late = wall - frame.published_wall > timeout
        else:
            late = frame.stamp_ns == 0 and wall - frame.asked_wall > timeout
        if late:
            self.frame = None
            self.answering = self.answering and frame.published_wall is None  # a lost verdict: vi_node is gone
            return frame
        return None

    def failed(self, frame: Frame) -> None:
        """No frame came of the snapshot (rendering failed): give it up."""
        if self.frame is frame:
            self.frame = None
