"""The remove-tile mission in a simulated M3 world, in simulated time: the base follows its drive
commands, the arm its joint goals, the laser is the URG emulator's ray caster over the tile's
outline. The gripper stops on the tile only when the tool point is inside the tile's outline, at
its height, the fingers across its width; the tile then moves with the tool until the gripper opens.
So a removal passes only when the laser found where the tile really lies and the arm went there."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pytest

from hardware_drivers.arm_kinematics import forward
from hardware_drivers.emulators.urg_emulator import LONG_RECTANGLE, parse_polygon, ray_cast
from hardware_drivers.laser_scan import LaserScanData
from hardware_drivers.place_tile_mission import MissionConfig
from hardware_drivers.planar_pose import Pose2D, wrap_angle
from hardware_drivers.remove_tile_mission import (
    RemovalOutcome,
    RemovalPhase,
    RemoveGoal,
    RemoveTileMission,
)
from hardware_drivers.scip import URG_04LX

CONFIG = MissionConfig()
JOINTS = (*CONFIG.arm_joints, CONFIG.gripper_joint)
ANGLES = np.array([URG_04LX.step_angle(s) for s in range(URG_04LX.amin, URG_04LX.amax + 1)])
FOOTPRINT = parse_polygon(LONG_RECTANGLE)
HEIGHT = 0.02
GRIPPER_ON_TILE = -0.2  # rad, where the fingers meet a 4 cm wide tile
BELIEVED = Pose2D(0.0, 0.0, 0.0)  # where tile 3 should lie
DROP_OFF = (0.45, -0.55, 0.0)
START = Pose2D(0.0, -0.5, math.pi / 2)  # the base, facing the structure


class SimulatedM3:
    """An M3 robot with perfect localization, on a floor with one long rectangle."""

    def __init__(self, tile: Pose2D | None) -> None:
        self.time = 100.0
        self.base = START
        self.command = (0.0, 0.0)
        self.tile = tile
        self.held: Pose2D | None = None  # the tile in the tool's frame while the fingers hold it
        self.slippery = False  # the fingers slide off the tile: they close on nothing
        self.positions = dict.fromkeys(JOINTS, 0.0)
        self.velocities = dict.fromkeys(JOINTS, 0.0)
        self.goals = dict(self.positions)
        self.fault_from = math.inf
        self.cancel_requested = False
        self.stops = 0
        self.rng = np.random.default_rng(7)

    # ------------------------------------------------------------------ M3Hardware
    def now(self) -> float:
        return self.time

    def sleep(self, seconds: float) -> None:
        linear, angular = self.command
        yaw = self.base.yaw + angular * seconds / 2
        self.base = Pose2D(self.base.x + linear * seconds * math.cos(yaw),
                           self.base.y + linear * seconds * math.sin(yaw),
                           wrap_angle(self.base.yaw + angular * seconds))
        for name, goal in self.goals.items():
            position = self.positions[name]
            target = position + max(-seconds, min(seconds, goal - position))
            if name == CONFIG.gripper_joint:
                target = self._fingers(position, target)
            self.velocities[name] = (target - position) / seconds
            self.positions[name] = target
        if self.held is not None:
            self.tile = self.tool().compose(self.held)
        self.time += seconds

    def map_pose(self) -> Pose2D:
        return self.base

    def drive(self, linear: float, angular: float) -> None:
        self.command = (linear, angular)

    def stop(self) -> None:
        self.command = (0.0, 0.0)
        self.stops += 1

    def scan_after(self, stamp: float, timeout: float) -> LaserScanData:
        self.sleep(0.1)
        laser = self.base.compose(Pose2D(*CONFIG.laser_mount))
        segments = np.zeros((0, 4))
        if self.tile is not None and self.held is None:  # a lifted tile is above the laser's plane
            corners = self.tile.transform_points(FOOTPRINT)
            segments = np.hstack([corners, np.roll(corners, -1, axis=0)])
        ranges = np.round(ray_cast(laser, ANGLES, segments) + self.rng.normal(0.0, 0.003, len(ANGLES)), 3)
        ranges[(ranges < 0.02) | (ranges > 5.6)] = np.nan
        return LaserScanData(self.time, float(ANGLES[0]), URG_04LX.angle_increment, ranges, 0.02, 5.6)

    def joints(self) -> dict[str, tuple[float, float]]:
        return {n: (self.positions[n], self.velocities[n]) for n in JOINTS}

    def move_joints(self, goals: dict[str, float], duration: float) -> None:
        self.goals.update(goals)

    def hazard(self) -> None:
        return None

    def fault(self) -> str | None:
        return "crustcrawler_arm: no joint_states for 1 s (arm not answering?)" if self.time >= self.fault_from \
            else None

    def canceled(self) -> bool:
        return self.cancel_requested

    # ------------------------------------------------------------------ the world
    def tool(self) -> Pose2D:
        """The tool point on the floor plane, its yaw the grasp yaw (the yaw of a tile it grips)."""
        tool = forward(CONFIG.geometry, [self.positions[n] for n in CONFIG.arm_joints])
        arm = self.base.compose(Pose2D(CONFIG.arm_mount[0], CONFIG.arm_mount[1], CONFIG.arm_mount[3]))
        return arm.compose(Pose2D(tool.x, tool.y, tool.grasp_yaw()))

    def tool_height(self) -> float:
        return forward(CONFIG.geometry, [self.positions[n] for n in CONFIG.arm_joints]).z + CONFIG.arm_mount[2]

    def _fingers(self, position: float, target: float) -> float:
        if self.held is not None:
            if target > GRIPPER_ON_TILE + 0.05:
                self.held = None  # opened: the tile stays where it is
            return max(target, GRIPPER_ON_TILE)
        if target < GRIPPER_ON_TILE <= position and self._between_fingers():
            self.held = self.tool().inverse().compose(self.tile)
            return GRIPPER_ON_TILE
        return target

    def _between_fingers(self) -> bool:
        if self.tile is None or self.slippery:
            return False
        tool = self.tool()
        in_tile = self.tile.inverse().compose(tool)
        inside = bool(np.all(abs(np.array([in_tile.x, in_tile.y])) < FOOTPRINT.max(axis=0)))  # a rectangle
        across = abs(math.remainder(tool.yaw - self.tile.yaw, math.pi)) < math.radians(10)
        return inside and across and 0.0 < self.tool_height() < HEIGHT


def _goal() -> RemoveGoal:
    return RemoveGoal(tile_id=3, tile_type="long_rectangle", footprint=FOOTPRINT, height=HEIGHT,
                      pose=BELIEVED, z=0.0, drop_off=DROP_OFF)


def _run(world: SimulatedM3, on_feedback: Callable[[RemovalPhase, float], None] = lambda p, f: None,
         ) -> tuple[object, list[RemovalPhase], list[str]]:
    phases: list[RemovalPhase] = []
    log: list[str] = []

    def feedback(phase: RemovalPhase, progress: float, pose: Pose2D | None) -> None:
        phases.append(phase)
        on_feedback(phase, progress)

    result = RemoveTileMission(world, CONFIG, feedback, log.append).run(_goal())
    return result, phases, log


def _order(phases: list[RemovalPhase]) -> list[RemovalPhase]:
    return [p for i, p in enumerate(phases) if i == 0 or phases[i - 1] != p]


@pytest.mark.parametrize("truth", [Pose2D(0.03, -0.015, math.radians(30)), Pose2D(-0.02, 0.025, math.radians(-45))],
                         ids=["3cm_30deg", "3cm_minus_45deg"])
def test_a_shifted_and_turned_tile_is_found_lifted_and_left_at_the_drop_off(truth: Pose2D) -> None:
    world = SimulatedM3(tile=truth)
    result, phases, log = _run(world)
    assert result.outcome == RemovalOutcome.SUCCEEDED, result.message
    assert result.message == ""
    assert _order(phases) == list(RemovalPhase)
    found = result.found_pose
    assert found.distance_to(truth) < 0.01
    assert abs(math.remainder(found.yaw - truth.yaw, math.pi)) < math.radians(5)
    shift = BELIEVED.distance_to(truth) * 100
    assert f"tile 3 lies {shift:.1f} cm and {abs(math.degrees(truth.yaw)):.0f} deg from its believed pose" \
        in "\n".join(log)
    # the tile was gripped (only possible where it really lay) and now lies at the drop-off
    assert world.held is None
    assert math.hypot(world.tile.x - DROP_OFF[0], world.tile.y - DROP_OFF[1]) < 0.01
    assert world.positions[CONFIG.gripper_joint] > CONFIG.gripper_open - CONFIG.joint_tolerance
    # backed away from it, wheels stopped
    assert math.hypot(world.base.x - DROP_OFF[0], world.base.y - DROP_OFF[1]) > CONFIG.place_standoff + 0.05
    assert world.command == (0.0, 0.0)
    assert 0 < result.duration < 120


@pytest.mark.parametrize("tile", [None, Pose2D(0.3, 0.05, 0.0)], ids=["nothing_there", "tile_30cm_away"])
def test_no_tile_near_the_believed_pose_fails_with_not_found(tile: Pose2D | None) -> None:
    world = SimulatedM3(tile=tile)
    result, phases, _ = _run(world)
    assert result.outcome == RemovalOutcome.FAILED_NOT_FOUND
    assert result.message.startswith("no long_rectangle found by the laser near tile 3's believed pose (no cluster")
    assert "\n" not in result.message
    assert result.found_pose is None
    assert phases[-1] == RemovalPhase.LOCATING_TILE
    assert world.command == (0.0, 0.0) and world.tile == tile


def test_a_gripper_closing_on_nothing_fails_with_grasp_error_and_says_where_the_tile_is() -> None:
    truth = Pose2D(0.02, 0.01, math.radians(20))
    world = SimulatedM3(tile=truth)
    world.slippery = True
    result, phases, _ = _run(world)
    assert result.outcome == RemovalOutcome.FAILED_GRASP
    assert result.message == "the gripper closed on nothing: the tile was not grasped"
    assert phases[-1] == RemovalPhase.LIFTING
    assert result.found_pose.distance_to(truth) < 0.01
    assert world.tile == truth
    assert world.positions[CONFIG.gripper_joint] > CONFIG.gripper_open - CONFIG.joint_tolerance  # opened again


def test_a_cancel_while_carrying_the_tile_stops_the_wheels_at_once() -> None:
    world = SimulatedM3(tile=Pose2D(0.0, 0.0, 0.0))
    canceled_at: list[float] = []

    def cancel_on_the_way(phase: RemovalPhase, progress: float) -> None:
        if phase == RemovalPhase.DRIVING_TO_DROP_OFF and progress > 0.2 and not canceled_at:
            assert world.command != (0.0, 0.0)
            world.cancel_requested = True
            canceled_at.append(world.time)

    result, phases, _ = _run(world, cancel_on_the_way)
    assert canceled_at
    assert (result.outcome, result.message) == (RemovalOutcome.CANCELED, "canceled")
    assert phases[-1] == RemovalPhase.DRIVING_TO_DROP_OFF
    assert world.command == (0.0, 0.0)
    assert world.time - canceled_at[0] <= 2 * CONFIG.control_period
    assert result.found_pose is not None and world.held is not None  # it still holds the tile


def test_a_device_fault_that_lasts_fails_with_hardware_error() -> None:
    world = SimulatedM3(tile=Pose2D(0.0, 0.0, 0.0))
    faulted: list[float] = []

    def fault_while_lifting(phase: RemovalPhase, progress: float) -> None:
        if phase == RemovalPhase.LIFTING and not faulted:
            world.fault_from = world.time
            faulted.append(world.time)

    result, phases, _ = _run(world, fault_while_lifting)
    assert result.outcome == RemovalOutcome.FAILED_HARDWARE
    assert result.message == "crustcrawler_arm: no joint_states for 1 s (arm not answering?)"
    assert phases[-1] == RemovalPhase.LIFTING
    assert world.time - faulted[0] == pytest.approx(CONFIG.fault_grace, abs=3 * CONFIG.control_period)
    assert world.command == (0.0, 0.0)
