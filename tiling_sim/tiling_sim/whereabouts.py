"""Where every simulated robot truly stands, at every moment of simulated time, in the world process.

A robot's body runs in a process of its own (on its own host under `--hosts netns`), and news of
it crosses a network. So the body does not report where it got to after the fact: when it starts a
phase of its work, it tells the world where its base will stand once the phase ends and from which
moment of simulated time (`/sim/motion`). The world moves the robot there when its clock reaches
that moment, before anything else happens at that time, so a Kinect frame or an overhead pose of
any moment shows every robot where it truly stands then, however late the body's messages run.
Bases move from stop to stop (as they did when the world was one process): a robot driving is
seen where it started until it arrives.
"""

from __future__ import annotations

import heapq
import itertools

from tiling_sim.overhead_cameras import Pose2


class Whereabouts:
    def __init__(self, starts: dict[str, Pose2]) -> None:
        self.poses = dict(starts)  # where each robot stands now
        self._coming: list[tuple[float, int, str, Pose2]] = []  # (arrive_at, order, robot, pose)
        self._order = itertools.count()

    def knows(self, robot: str) -> bool:
        return robot in self.poses

    def expect(self, robot: str, arrive_at: float, pose: Pose2) -> None:
        """`robot` will stand at `pose` from `arrive_at` (s of simulated time) on."""
        if robot not in self.poses:
            raise ValueError(f"unknown robot '{robot}'")
        heapq.heappush(self._coming, (arrive_at, next(self._order), robot, pose))

    def arrive(self, now: float) -> list[str]:
        """Move every robot due at `now`; the robots that stopped, in the order they stopped."""
        stopped = []
        while self._coming and self._coming[0][0] <= now:
            _, _, robot, pose = heapq.heappop(self._coming)
            self.poses[robot] = pose
            stopped.append(robot)
        return stopped


def standing_at(t: float, standing: Pose2, drive: tuple[float, Pose2] | None) -> Pose2:
    """Where a robot that stands at `standing`, and is driving to drive[1] arriving at drive[0] (s), stands
    at `t` (s of the world's time), as `Whereabouts` has it: at the goal from the arrival on. A body whose
    clock lags the world's (a busy host) asks this for a frame the world stamped after its arrival."""
    if drive is not None and t >= drive[0]:
        return drive[1]
    return standing

