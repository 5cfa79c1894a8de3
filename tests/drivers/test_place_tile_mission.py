"""The place-tile mission's arm steps against a simulated arm whose commands can be lost on the way
(as a trajectory message or a goal write can be): a lost step is sent once more, an arm that never
follows fails the mission with the reason. Simulated time: no test waits for real seconds."""

from __future__ import annotations

import re

import numpy as np
import pytest

from hardware_drivers.place_tile_mission import (
    MissionConfig,
    MissionFailedError,
    Outcome,
    PlaceGoal,
    PlaceTileMission,
)
from hardware_drivers.planar_pose import Pose2D

CONFIG = MissionConfig(arm_speed=1.0)
JOINTS = (*CONFIG.arm_joints, CONFIG.gripper_joint)
CARRY = dict(zip(CONFIG.arm_joints, CONFIG.carry_pose, strict=True))


class SimulatedArm:
    """An M3 robot standing still whose joints follow their goals at `speed` rad/s; the first
    `lost_commands` commands never arrive. A tile between the fingers stops the gripper at
    `gripper_stop`."""

    def __init__(self, lost_commands: int = 0, gripper_stop: float | None = None, speed: float = 1.0) -> None:
        self.time = 100.0
        self.positions = dict.fromkeys(JOINTS, 0.0)
        self.velocities = dict.fromkeys(JOINTS, 0.0)
        self.goals = dict(self.positions)
        self.commands: list[tuple[float, dict[str, float]]] = []
        self.lost_commands = lost_commands
        self.gripper_stop = gripper_stop
        self.speed = speed
        self.fault_between = (0.0, 0.0)  # (from, to): the times a device fault is reported
        self.no_joints_between = (0.0, 0.0)  # the times no fresh joint states are at hand
        self.stops = 0

    def now(self) -> float:
        return self.time

    def sleep(self, seconds: float) -> None:
        for name, goal in self.goals.items():
            position = self.positions[name]
            step = max(-self.speed * seconds, min(self.speed * seconds, goal - position))
            target = position + step
            if name == CONFIG.gripper_joint and self.gripper_stop is not None:
                target = max(target, self.gripper_stop)
            self.velocities[name] = (target - position) / seconds
            self.positions[name] = target
        self.time += seconds

    def map_pose(self) -> Pose2D:
        return Pose2D(0.0, 0.0, 0.0)

    def drive(self, linear: float, angular: float) -> None:
        pass

    def stop(self) -> None:
        self.stops += 1

    def scan_after(self, stamp: float, timeout: float) -> None:
        return None

    def joints(self) -> dict[str, tuple[float, float]] | None:
        if self.no_joints_between[0] <= self.time < self.no_joints_between[1]:
            return None
        return {n: (self.positions[n], self.velocities[n]) for n in JOINTS}

    def move_joints(self, goals: dict[str, float], duration: float) -> None:
        self.commands.append((self.time, dict(goals)))
        if self.lost_commands > 0:
            self.lost_commands -= 1
            return
        self.goals.update(goals)

    def hazard(self) -> None:
        return None

    def fault(self) -> str | None:
        if self.fault_between[0] <= self.time < self.fault_between[1]:
            return "create_base: no odom for 1 s (base not answering?)"
        return None

    def canceled(self) -> bool:
        return False


def mission(arm: SimulatedArm, log: list[str]) -> PlaceTileMission:
    return PlaceTileMission(arm, CONFIG, log=log.append)


def test_an_arm_step_that_was_lost_is_sent_again_and_reached() -> None:
    arm = SimulatedArm(lost_commands=1)
    log: list[str] = []
    mission(arm, log)._move_arm(CARRY, "carry pose")
    assert [goals for _, goals in arm.commands] == [CARRY, CARRY]
    # noticed by the arm not starting to move, not after the whole move's timeout
    assert arm.commands[1][0] - arm.commands[0][0] <= CONFIG.arm_stall_time + 2 * CONFIG.control_period
    assert all(abs(arm.positions[n] - v) <= CONFIG.joint_tolerance for n, v in CARRY.items())
    assert len(log) == 1 and re.fullmatch(r"the arm did not reach carry pose \(no joint moved towards the goal; "
                                          r"elbow is 1\.90 rad off after 1\.\d s\); sending the goal again", log[0])


def test_an_arm_that_never_follows_fails_the_mission_with_the_reason() -> None:
    arm = SimulatedArm(lost_commands=10)
    goal = PlaceGoal(tile_id=3, tile_type="square", footprint=np.array([[0, 0], [0.04, 0], [0.04, 0.04]]),
                     height=0.04, pose=Pose2D(0.0, 0.0, 0.0), z=0.0, cache=(0.0, -1.0))
    result = mission(arm, []).run(goal)
    assert result.outcome == Outcome.FAILED_HARDWARE
    assert re.fullmatch(r"the arm did not reach carry pose with the gripper open: no joint moved towards the "
                        r"goal; elbow is 1\.90 rad off after 1\.\d s \(goal sent 2 times\)", result.message)
    assert len(arm.commands) == CONFIG.arm_attempts == 2


def test_an_arm_that_stops_short_is_sent_again_once_then_fails() -> None:
    arm = SimulatedArm()
    log: list[str] = []
    # the elbow follows the first command only part of the way (a servo that lost torque, say)
    arm.sleep = _stopping_elbow(arm, at=-1.0)  # type: ignore[method-assign]
    with pytest.raises(MissionFailedError) as failure:
        mission(arm, log)._move_arm(CARRY, "carry pose")
    assert failure.value.outcome == Outcome.FAILED_HARDWARE
    assert failure.value.message.startswith("the arm did not reach carry pose: no joint moved towards the goal; "
                                            "elbow is 0.90 rad off")
    # the first attempt moved, so it waited for the planned 1.9 s and arm_timeout
    assert re.match(r"the arm did not reach carry pose \(elbow is 0\.90 rad off after 7\.9 s\)", log[0])
    assert len(arm.commands) == 2


def _stopping_elbow(arm: SimulatedArm, at: float):  # type: ignore[no-untyped-def]
    move = arm.sleep

    def sleep(seconds: float) -> None:
        move(seconds)
        arm.positions["elbow"] = max(arm.positions["elbow"], at)

    return sleep


def test_a_lost_gripper_close_is_sent_again_and_stops_on_the_tile() -> None:
    arm = SimulatedArm(gripper_stop=-0.2)
    arm.positions[CONFIG.gripper_joint] = arm.goals[CONFIG.gripper_joint] = CONFIG.gripper_open
    arm.lost_commands = 1
    log: list[str] = []
    position = mission(arm, log)._close_gripper()
    assert position == pytest.approx(-0.2)
    assert [goals for _, goals in arm.commands] == [{CONFIG.gripper_joint: CONFIG.gripper_closed}] * 2
    assert log == ["the gripper did not start closing; sending the goal again"]


def test_a_gripper_that_never_closes_fails_instead_of_passing_for_a_grasp() -> None:
    arm = SimulatedArm(lost_commands=10)
    arm.positions[CONFIG.gripper_joint] = arm.goals[CONFIG.gripper_joint] = CONFIG.gripper_open
    with pytest.raises(MissionFailedError) as failure:
        mission(arm, [])._close_gripper()
    assert failure.value.outcome == Outcome.FAILED_HARDWARE
    assert failure.value.message == "the gripper did not start closing within 1.5 s (goal sent 2 times)"


def test_a_fault_that_clears_within_the_grace_stops_the_wheels_and_the_mission_goes_on() -> None:
    arm = SimulatedArm()
    arm.fault_between = (arm.time + 0.2, arm.time + 0.2 + CONFIG.fault_grace * 0.6)  # a busy host
    arm.no_joints_between = (arm.time + 1.5, arm.time + 1.8)
    log: list[str] = []
    mission(arm, log)._move_arm(CARRY, "carry pose")
    assert arm.stops == 2
    assert log == [f"going on: the problem cleared within {CONFIG.fault_grace:g} s"] * 2


def test_a_fault_that_lasts_ends_the_mission_with_it() -> None:
    arm = SimulatedArm()
    start = arm.time
    arm.fault_between = (start + 0.2, start + 60.0)
    with pytest.raises(MissionFailedError) as failure:
        mission(arm, [])._move_arm(CARRY, "carry pose")
    assert failure.value.outcome == Outcome.FAILED_HARDWARE
    assert failure.value.message == "create_base: no odom for 1 s (base not answering?)"
    assert arm.time - (start + 0.2) == pytest.approx(CONFIG.fault_grace, abs=2 * CONFIG.control_period)
    assert arm.stops >= 1


def test_joint_states_that_stay_away_end_the_mission() -> None:
    arm = SimulatedArm()
    arm.no_joints_between = (arm.time + 0.2, arm.time + 60.0)
    with pytest.raises(MissionFailedError) as failure:
        mission(arm, [])._move_arm(CARRY, "carry pose")
    assert (failure.value.outcome, failure.value.message) == (Outcome.FAILED_HARDWARE,
                                                              "no fresh joint states from the arm")
