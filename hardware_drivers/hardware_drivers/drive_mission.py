"""The M3 robot driving its base to a pose with nothing to handle, no ROS (beyond the paper).

An assembly robot with nothing left to place goes home, out of the scanning robots' view
(assembly_node's parking); `m3_robot` serves it as ``navigate_to``. The arm goes to the carry pose
first, gripper open, so that it sticks out least on the way; then the base drives to the pose with
the same controller, checks and timeout as a placement's drives (:class:`TileMission`). Failures
end it with one line: FAILED_NAVIGATION (no pose, timeout, bumper or wheel drop), FAILED_HARDWARE,
CANCELED; the wheels are stopped on every exit.
"""

from __future__ import annotations

from collections.abc import Callable
from enum import IntEnum

from hardware_drivers.place_tile_mission import (
    M3Hardware,
    MissionConfig,
    MissionFailedError,
    MissionResult,
    Outcome,
    PhaseFeedback,
    TileMission,
)
from hardware_drivers.planar_pose import Pose2D


class DrivePhase(IntEnum):
    DRIVING = 1  # NavigateTo has no phases: its feedback is the pose and the distance left


class DriveMission(TileMission):
    def __init__(self, hardware: M3Hardware, config: MissionConfig, feedback: PhaseFeedback | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        super().__init__(hardware, config, feedback, log, DrivePhase.DRIVING)

    def run(self, goal: Pose2D, what: str = "the goal") -> MissionResult:
        """Drive to `goal` (map); `placed_pose` of the result is where the base stopped."""
        ended, duration = self._stopping(lambda: self._run(goal, what))
        if isinstance(ended, MissionFailedError):
            return MissionResult(ended.outcome, ended.message, duration=duration)
        return MissionResult(Outcome.SUCCEEDED, "", ended, duration=duration)

    def _run(self, goal: Pose2D, what: str) -> Pose2D:
        self._prepare()
        self._drive_to(goal, what)
        return self._pose()
