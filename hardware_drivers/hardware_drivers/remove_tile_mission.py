"""Taking one tile off the structure with an M3 robot, no ROS: the repair of a tile placed wrong.

Beyond the paper: its future work names "online adaptation of the assembly strategy in the presence
of incorrect tile placements"; the assembly node repairs a misplaced tile by having it taken off
(this mission) and placed again. The tile may lie a few centimetres from where it should, turned
(up to 45 degrees is expected); the laser finds where it really is. One mission, in the phases of
the RemoveTile action:

1. DRIVING_TO_STRUCTURE: carry pose, gripper open, drive to face the tile's believed pose at
   ``place_standoff``;
2. LOCATING_TILE: find the tile's footprint in fresh laser scans within ``structure_search_radius``
   of the believed pose, moving the base (at most ``max_adjustments`` times) when it lies outside
   the arm's comfortable reach; where it was found is logged and returned;
3. LIFTING: above the found tile, down, close the gripper (it must stop on the tile), lift, carry
   pose;
4. DRIVING_TO_DROP_OFF: drive to face the drop-off at ``place_standoff``;
5. RELEASING: put the tile down at the drop-off, turned as it hangs in the fingers, and let go;
6. RETREATING: lift, carry pose, back away.

Failures end the mission with a RemoveTile result code and one line: FAILED_NAVIGATION (no pose,
timeout, bumper or wheel drop, the drop-off out of reach from where the base stopped),
FAILED_NOT_FOUND (nothing of the tile's outline near its pose), FAILED_GRASP (out of the arm's
reach, gripper closed on nothing, tile dropped), FAILED_HARDWARE, CANCELED; the wheels are stopped on
every exit. FAILED_TILE_ON_TOP and ALREADY_ABSENT need a view of the structure from above that a
laser in the floor plane does not give: this mission never returns them.

The steps, their checks and the configuration are place_tile_mission's (:class:`TileMission`,
:class:`MissionConfig`), on the same :class:`M3Hardware`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

from hardware_drivers.place_tile_mission import (
    M3Hardware,
    MissionConfig,
    MissionFailedError,
    Outcome,
    TileMission,
)
from hardware_drivers.planar_pose import Pose2D, wrap_angle
from hardware_drivers.tile_localization import rotational_symmetry


class RemovalPhase(IntEnum):
    """tiling_assembly_msgs/action/RemoveTile feedback phases."""

    DRIVING_TO_STRUCTURE = 1
    LOCATING_TILE = 2
    LIFTING = 3
    DRIVING_TO_DROP_OFF = 4
    RELEASING = 5
    RETREATING = 6


class RemovalOutcome(IntEnum):
    """tiling_assembly_msgs/action/RemoveTile result codes."""

    SUCCEEDED = 0
    FAILED_NAVIGATION = 1
    FAILED_NOT_FOUND = 2
    FAILED_GRASP = 3
    FAILED_TILE_ON_TOP = 4
    FAILED_HARDWARE = 5
    CANCELED = 6
    ALREADY_ABSENT = 7


# the shared steps fail with place_tile_mission's outcomes
_OUTCOME = {
    Outcome.FAILED_NAVIGATION: RemovalOutcome.FAILED_NAVIGATION,
    Outcome.FAILED_NO_TILE: RemovalOutcome.FAILED_NOT_FOUND,
    Outcome.FAILED_GRASP: RemovalOutcome.FAILED_GRASP,
    Outcome.FAILED_HARDWARE: RemovalOutcome.FAILED_HARDWARE,
    Outcome.CANCELED: RemovalOutcome.CANCELED,
}


@dataclass(frozen=True)
class RemoveGoal:
    tile_id: int
    tile_type: str
    footprint: NDArray[np.float64]  # (N, 2) outline in the tile frame
    height: float  # m
    pose: Pose2D  # where the tile frame is believed to lie, in the map
    z: float  # m, height of the tile's bottom
    drop_off: tuple[float, float, float]  # m, where to leave it (map), z of its bottom there


@dataclass(frozen=True)
class RemovalResult:
    outcome: RemovalOutcome
    message: str
    found_pose: Pose2D | None = None  # where the laser found the tile (map), also when the lift failed
    found_z: float = 0.0  # m, the believed bottom height (a laser in the floor plane measures no height)
    duration: float = 0.0


RemovalFeedback = Callable[[RemovalPhase, float, Pose2D | None], None]


class RemoveTileMission(TileMission):
    def __init__(self, hardware: M3Hardware, config: MissionConfig, feedback: RemovalFeedback | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        super().__init__(hardware, config, feedback, log, RemovalPhase.DRIVING_TO_STRUCTURE)
        self.found: Pose2D | None = None

    def run(self, goal: RemoveGoal) -> RemovalResult:
        self.found = None
        ended, duration = self._stopping(lambda: self._run(goal))
        if isinstance(ended, MissionFailedError):
            return RemovalResult(_OUTCOME[ended.outcome], ended.message, self.found, goal.z, duration)
        return RemovalResult(RemovalOutcome.SUCCEEDED, "", self.found, goal.z, duration)

    def _run(self, goal: RemoveGoal) -> None:
        cfg = self.config
        believed = (goal.pose.x, goal.pose.y)
        self.phase = RemovalPhase.DRIVING_TO_STRUCTURE
        self._prepare()
        self._approach(believed, cfg.place_standoff, f"tile {goal.tile_id} at ({believed[0]:.2f}, {believed[1]:.2f})")

        self.phase = RemovalPhase.LOCATING_TILE
        tile = self._locate_tile(goal.footprint, believed, cfg.structure_search_radius, goal.tile_type,
                                 f"tile {goal.tile_id}'s believed pose")
        self.found = tile.in_map
        self.log(_deviation(goal, tile.in_map))

        self.phase = RemovalPhase.LIFTING
        offset = self._grasp(tile.in_arm, goal.z, goal.height)

        self.phase = RemovalPhase.DRIVING_TO_DROP_OFF
        drop = goal.drop_off
        self._approach(drop[:2], cfg.place_standoff, f"the drop-off at ({drop[0]:.2f}, {drop[1]:.2f})")

        self.phase = RemovalPhase.RELEASING
        released, _, q_above = self._put_down(self._drop_pose(drop, offset), drop[2], goal.height, goal.footprint,
                                              offset, "the drop-off")
        self.log(f"left tile {goal.tile_id} at {released}")

        self.phase = RemovalPhase.RETREATING
        self._retreat(q_above)

    def _drop_pose(self, drop: tuple[float, float, float], offset: float) -> Pose2D:
        """The drop-off with the yaw the tile has there when the wrist does not roll: any yaw will
        do, and an unrolled wrist keeps clear of its limits."""
        arm = self._pose().compose(self.arm_mount)
        in_arm = arm.inverse().transform_points(np.array([drop[:2]]))[0]
        return Pose2D(drop[0], drop[1], wrap_angle(arm.yaw + math.atan2(in_arm[1], in_arm[0]) + offset))


def _deviation(goal: RemoveGoal, found: Pose2D) -> str:
    period = 2.0 * math.pi / rotational_symmetry(goal.footprint)
    turned = abs(math.remainder(found.yaw - goal.pose.yaw, period))
    return (f"tile {goal.tile_id} lies {goal.pose.distance_to(found) * 100:.1f} cm and "
            f"{math.degrees(turned):.0f} deg from its believed pose {goal.pose}")
