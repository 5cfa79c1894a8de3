"""Placing one tile with an M3 robot (paper section 3.1), no ROS.

"Each robot was given the global position of the structure's center and the positions of their
respective parts cache ... The LRF was used by the assembly robots to detect, pick, and place the
tiles." One mission, in the phases of the PlaceTile action:

1. DRIVING_TO_CACHE: stow the arm, open the gripper, drive (odometry corrected by the overhead
   cameras) to a pose facing the tile type's cache at ``pick_standoff``;
2. LOCATING_TILE: find the tile's footprint in fresh laser scans near the cache point; if it lies
   outside the arm's comfortable reach, move the base (at most ``max_adjustments`` times) and look
   again;
3. PICKING: above the tile, down, close the gripper (it must stop on the tile, not close fully),
   lift, carry pose; the tile's yaw in the fingers is remembered;
4. DRIVING_TO_STRUCTURE: drive to a pose facing the goal at ``place_standoff``;
5. PLACING: above the goal, down, release; the placed pose comes from the measured joints;
6. RETREATING: lift, carry pose, back away.

Failures end the mission with a result code and one line: FAILED_NAVIGATION (no pose, timeout,
bumper or wheel drop, goal out of reach from where the base stopped), FAILED_NO_TILE, FAILED_GRASP
(tile out of the arm's reach, gripper closed on nothing, tile dropped), FAILED_HARDWARE (a device
stopped answering or reports a fault for ``fault_grace``, the wheels stopped meanwhile; or the arm
did not follow a step sent twice: a step no joint starts on within ``arm_stall_time``, or that does
not arrive, is sent once more), CANCELED. The wheels are stopped on every exit.

The robot is reached through :class:`M3Hardware`, so the same mission runs on the real drivers'
topics or on anything else that provides them. Its steps (:class:`TileMission`) also take a tile
off the structure (remove_tile_mission).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from enum import IntEnum
from typing import NamedTuple, Protocol, TypeVar

import numpy as np
from numpy.typing import NDArray

from hardware_drivers.arm_kinematics import ArmGeometry, UnreachableError, forward, top_down_grasp
from hardware_drivers.base_navigation import GoToPose, GoToPoseParams, approach_pose
from hardware_drivers.laser_scan import LaserScanData
from hardware_drivers.planar_pose import Pose2D, wrap_angle
from hardware_drivers.tile_localization import (
    LocalizationParams,
    TileDetection,
    explain_no_tile,
    find_tile,
    rotational_symmetry,
)

T = TypeVar("T")


class Phase(IntEnum):
    """tiling_assembly_msgs/action/PlaceTile feedback phases."""

    DRIVING_TO_CACHE = 1
    LOCATING_TILE = 2
    PICKING = 3
    DRIVING_TO_STRUCTURE = 4
    PLACING = 5
    RETREATING = 6


class Outcome(IntEnum):
    """tiling_assembly_msgs/action/PlaceTile result codes."""

    SUCCEEDED = 0
    FAILED_NAVIGATION = 1
    FAILED_NO_TILE = 2
    FAILED_GRASP = 3
    FAILED_PRECONDITION = 4
    FAILED_HARDWARE = 5
    CANCELED = 6


class MissionFailedError(Exception):
    def __init__(self, outcome: Outcome, message: str) -> None:
        super().__init__(message)
        self.outcome = outcome
        self.message = message


class M3Hardware(Protocol):
    """What the mission needs from the robot."""

    def now(self) -> float: ...  # s, monotonic
    def sleep(self, seconds: float) -> None: ...
    def map_pose(self) -> Pose2D | None: ...  # base_link in the map; None until localized
    def drive(self, linear: float, angular: float) -> None: ...
    def stop(self) -> None: ...
    def scan_after(self, stamp: float, timeout: float) -> LaserScanData | None: ...  # taken after stamp
    def joints(self) -> Mapping[str, tuple[float, float]] | None: ...  # name -> (position, velocity)
    def move_joints(self, goals: Mapping[str, float], duration: float) -> None: ...
    def hazard(self) -> str | None: ...  # bumper pressed or wheel dropped
    def fault(self) -> str | None: ...  # a device stopped answering or reports an error
    def canceled(self) -> bool: ...


@dataclass(frozen=True)
class MissionConfig:
    geometry: ArmGeometry = field(default_factory=ArmGeometry)
    arm_joints: tuple[str, ...] = ("base_yaw", "shoulder", "elbow", "wrist_pitch", "wrist_roll")
    gripper_joint: str = "gripper"
    gripper_open: float = 0.6  # rad
    gripper_closed: float = -0.6  # rad
    carry_pose: tuple[float, ...] = (0.0, 1.2, -1.9, -0.8, 0.0)  # rad, arm joints while driving
    # the arm base in base_link: x, y, z (m), yaw (rad)
    arm_mount: tuple[float, float, float, float] = (0.10, 0.0, 0.07, 0.0)
    laser_mount: tuple[float, float, float] = (0.16, 0.0, 0.0)  # x, y (m), yaw of the laser in base_link
    pick_standoff: float = 0.35  # m from base_link to the cache point when stopping
    place_standoff: float = 0.32  # m from base_link to the goal when stopping
    preferred_reach: float = 0.22  # m from the arm base to the tile for picking
    reach_tolerance: float = 0.05  # m
    max_adjustments: int = 2
    cache_search_radius: float = 0.2  # m around the cache point
    # m around a tile's believed pose on the structure: the laser's points of a tile shifted a few cm
    # lie up to half its length further (a long rectangle seen end-on)
    structure_search_radius: float = 0.14
    scans_per_attempt: int = 3
    # the base counts as still when its map pose moves less than this over settle_time
    settle_distance: float = 0.002  # m
    settle_angle: float = 0.005  # rad
    settle_time: float = 0.3  # s
    settle_timeout: float = 3.0  # s, then the tile is looked for anyway
    approach_height: float = 0.05  # m above the grasp height
    grasp_height_fraction: float = 0.5  # grasp at this fraction of the tile's height
    release_clearance: float = 0.003  # m above the goal when opening the gripper
    arm_speed: float = 0.8  # rad/s for planned moves
    joint_tolerance: float = 0.04  # rad
    arm_timeout: float = 6.0  # s beyond a move's planned duration
    arm_stall_time: float = 1.5  # s after a command within which some joint must start moving
    arm_attempts: int = 2  # an arm step is sent this often before the mission fails
    fault_grace: float = 1.0  # s a device fault may last (wheels stopped) before the mission fails
    # s without a laser scan before the mission fails: long enough to ride out one reconnect of
    # the laser driver (its scan_timeout, retry_interval and the SCIP handshake take about 2 s)
    scan_wait: float = 5.0
    grasp_margin: float = 0.08  # rad: the gripper must stop this far from fully closed
    navigation: GoToPoseParams = field(default_factory=GoToPoseParams)
    navigation_timeout: float = 90.0  # s per drive
    localization_timeout: float = 5.0  # s to wait for a first pose
    retreat_distance: float = 0.10  # m backwards after placing
    control_period: float = 0.05  # s
    localization: LocalizationParams = field(default_factory=LocalizationParams)


@dataclass(frozen=True)
class PlaceGoal:
    tile_id: int
    tile_type: str
    footprint: NDArray[np.float64]  # (N, 2) outline in the tile frame
    height: float  # m
    pose: Pose2D  # goal of the tile frame in the map
    z: float  # m, goal height of the tile frame's origin (its bottom)
    cache: tuple[float, float]  # m, the type's parts cache in the map


@dataclass(frozen=True)
class MissionResult:
    outcome: Outcome
    message: str
    placed_pose: Pose2D | None = None
    placed_z: float = 0.0
    duration: float = 0.0


Feedback = Callable[[Phase, float, Pose2D | None], None]
PhaseFeedback = Callable[[IntEnum, float, Pose2D | None], None]


class Sighting(NamedTuple):
    """A tile the laser found: its frame in the arm base's frame and in the map."""

    in_arm: Pose2D
    in_map: Pose2D


class TileMission:
    """The building blocks of the M3 robot's missions with a tile (placing one here, taking one off
    the structure in remove_tile_mission): drive, find a tile with the laser, grasp, put down, back
    away; the fault, hazard and cancel checks throughout. A failure raises MissionFailedError with
    this module's `Outcome`; `phase` is the subclass's action's feedback phase."""

    def __init__(self, hardware: M3Hardware, config: MissionConfig, feedback: PhaseFeedback | None,
                 log: Callable[[str], None] | None, phase: IntEnum) -> None:
        self.hw = hardware
        self.config = config
        self.feedback = feedback or (lambda phase, progress, pose: None)
        self.log = log or (lambda text: None)
        mx, my, mz, myaw = config.arm_mount
        self.arm_mount = Pose2D(mx, my, myaw)
        self.arm_height = mz
        self.laser_mount = Pose2D(*config.laser_mount)
        self.phase = phase

    def _stopping(self, body: Callable[[], T]) -> tuple[T | MissionFailedError, float]:
        """What `body` returned, or the failure that ended it, and the time it took; the wheels are
        stopped on every exit."""
        start = self.hw.now()
        try:
            return body(), self.hw.now() - start
        except MissionFailedError as failure:
            self.hw.stop()
            return failure, self.hw.now() - start
        finally:
            self.hw.stop()

    # ------------------------------------------------------------------ steps
    def _prepare(self) -> None:
        """Once the base has a pose: carry pose, gripper open."""
        cfg = self.config
        self._wait_for_pose()
        self._report(0.0)
        self._move_arm({cfg.gripper_joint: cfg.gripper_open, **self._carry()},
                       "carry pose with the gripper open")

    def _approach(self, point: tuple[float, float], standoff: float, what: str) -> None:
        """Drive to face `point` (map) from `standoff`, coming from where the base is."""
        pose = self._pose()
        self._drive_to(approach_pose(point[0], point[1], pose.x, pose.y, standoff), what)

    def _locate_tile(self, footprint: NDArray[np.float64], near: tuple[float, float], radius: float,
                     tile_type: str, where: str) -> Sighting:
        """The tile of `footprint` the laser finds within `radius` of `near` (map), once it lies
        within the arm's comfortable reach (the base is moved at most ``max_adjustments`` times)."""
        cfg = self.config
        for attempt in range(cfg.max_adjustments + 1):
            self._report(attempt / (cfg.max_adjustments + 1))
            pose, detection = self._detect(footprint, near, radius, tile_type, where)
            tile_in_base = self.laser_mount.compose(detection.pose)
            tile_in_arm = self.arm_mount.inverse().compose(tile_in_base)
            tile_map = pose.compose(tile_in_base)
            self.log(f"found the {tile_type} at {tile_map} in the map ({detection})")
            reach = math.hypot(tile_in_arm.x, tile_in_arm.y)
            bearing = math.atan2(tile_in_arm.y, tile_in_arm.x)
            if abs(reach - cfg.preferred_reach) <= cfg.reach_tolerance and abs(bearing) < 0.6:
                self._report(1.0)
                return Sighting(tile_in_arm, tile_map)
            if attempt == cfg.max_adjustments:
                break
            # put the tile at the preferred reach straight ahead of the arm, then look again
            standoff = self.arm_mount.x + cfg.preferred_reach
            stop = approach_pose(tile_map.x, tile_map.y, pose.x, pose.y, standoff)
            self.log(f"tile {reach:.2f} m from the arm at {math.degrees(bearing):.0f} deg: moving the base")
            self._drive_to(stop, "a pose within the arm's reach of the tile", report=False)
        raise MissionFailedError(
            Outcome.FAILED_GRASP,
            f"the {tile_type} stays out of the arm's reach after {cfg.max_adjustments} moves",
        )

    def _detect(self, footprint: NDArray[np.float64], near: tuple[float, float], radius: float,
                tile_type: str, where: str) -> tuple[Pose2D, TileDetection]:
        """The base's settled pose and the tile found from there, in up to ``scans_per_attempt``
        fresh scans; FAILED_NO_TILE when none shows it."""
        cfg = self.config
        pose = self._settled_pose()
        reason = "no scan"
        for _ in range(cfg.scans_per_attempt):
            self._check()
            scan = self.hw.scan_after(self.hw.now(), timeout=cfg.scan_wait)
            if scan is None:
                raise MissionFailedError(Outcome.FAILED_HARDWARE,
                                         f"no laser scan for {cfg.scan_wait:g} s while locating the tile")
            if self._moved_since(pose):
                # the scan and the pose would disagree: wait for the base to stop, then look again
                pose = self._settled_pose()
                reason = "the base kept moving"
                continue
            near_in_laser = pose.compose(self.laser_mount).inverse().transform_points(np.array([near]))[0]
            region = (float(near_in_laser[0]), float(near_in_laser[1]), radius)
            detection = find_tile(scan, footprint, cfg.localization, region)
            if detection is not None:
                return pose, detection
            reason = explain_no_tile(scan, footprint, cfg.localization, region)
        raise MissionFailedError(Outcome.FAILED_NO_TILE,
                                 f"no {tile_type} found by the laser near {where} ({reason})")

    def _grasp(self, tile_in_arm: Pose2D, bottom_z: float, height: float) -> float:
        """Above the tile, down, close on it, lift, carry pose; the tile's yaw relative to the
        fingers (to put it down the right way round). `bottom_z`: the tile's bottom above the floor."""
        cfg = self.config
        g = cfg.geometry
        grasp_z = bottom_z + height * cfg.grasp_height_fraction - self.arm_height
        try:
            q_above = top_down_grasp(g, tile_in_arm.x, tile_in_arm.y, grasp_z + cfg.approach_height,
                                     tile_in_arm.yaw)
            q_grasp = top_down_grasp(g, tile_in_arm.x, tile_in_arm.y, grasp_z, tile_in_arm.yaw)
        except UnreachableError as error:
            raise MissionFailedError(Outcome.FAILED_GRASP, f"tile out of the arm's reach: {error}") from None
        self._report(0.1)
        above = dict(zip(cfg.arm_joints, q_above, strict=True))
        self._move_arm({**above, cfg.gripper_joint: cfg.gripper_open}, "above the tile")
        self._report(0.3)
        self._move_arm(dict(zip(cfg.arm_joints, q_grasp, strict=True)), "down to the tile")
        self._report(0.5)
        gripper = self._close_gripper()
        if gripper - cfg.gripper_closed < cfg.grasp_margin:
            self._move_arm({cfg.gripper_joint: cfg.gripper_open}, "open the empty gripper")
            raise MissionFailedError(Outcome.FAILED_GRASP,
                                     "the gripper closed on nothing: the tile was not grasped")
        offset = wrap_angle(tile_in_arm.yaw - forward(g, q_grasp).grasp_yaw())
        self._report(0.7)
        self._move_arm(dict(zip(cfg.arm_joints, q_above, strict=True)), "lift the tile")
        self._move_arm(self._carry(), "carry pose")
        joints = self._joints()
        if joints[cfg.gripper_joint][0] - cfg.gripper_closed < cfg.grasp_margin:
            raise MissionFailedError(Outcome.FAILED_GRASP,
                                     "the tile slipped out of the gripper while lifting")
        self._report(1.0)
        return offset

    def _put_down(self, target: Pose2D, z: float, height: float, footprint: NDArray[np.float64],
                  offset: float, what: str) -> tuple[Pose2D, float, tuple[float, ...]]:
        """Put the held tile down at `target` (map), its bottom at `z`, and let go; where it was
        released (from the measured joints), its bottom's height, and the joints above it."""
        cfg = self.config
        g = cfg.geometry
        pose = self._pose()
        target_in_arm = pose.compose(self.arm_mount).inverse().compose(target)
        release_z = z + height * cfg.grasp_height_fraction + cfg.release_clearance - self.arm_height
        period = 2.0 * math.pi / rotational_symmetry(footprint)
        problems = []
        solution = None
        # a symmetric tile may be put down turned by its symmetry: pick a wrist roll that fits
        for turn in sorted(range(-6, 7), key=abs):
            yaw = wrap_angle(target_in_arm.yaw - offset + turn * period)
            try:
                q_above = top_down_grasp(g, target_in_arm.x, target_in_arm.y, release_z + cfg.approach_height,
                                         yaw, allow_flip=False)
                q_release = top_down_grasp(g, target_in_arm.x, target_in_arm.y, release_z, yaw, allow_flip=False)
                solution = (q_above, q_release)
                break
            except UnreachableError as error:
                problems.append(str(error))
            if period >= 2.0 * math.pi - 1e-9:
                break
        if solution is None:
            raise MissionFailedError(
                Outcome.FAILED_NAVIGATION,
                f"{what} is out of the arm's reach from where the base stopped: {problems[0]}",
            )
        q_above, q_release = solution
        self._report(0.1)
        self._move_arm(dict(zip(cfg.arm_joints, q_above, strict=True)), f"above {what}")
        self._report(0.4)
        self._move_arm(dict(zip(cfg.arm_joints, q_release, strict=True)), f"down to {what}")
        joints = self._joints()
        measured = forward(g, [joints[name][0] for name in cfg.arm_joints])
        arm_in_map = self._pose().compose(self.arm_mount)
        tool = arm_in_map.compose(Pose2D(measured.x, measured.y, measured.grasp_yaw() + offset))
        released_z = measured.z + self.arm_height - height * cfg.grasp_height_fraction - cfg.release_clearance
        self._report(0.7)
        self._move_arm({cfg.gripper_joint: cfg.gripper_open}, "release the tile")
        self._report(1.0)
        return tool, released_z, q_above

    def _retreat(self, q_above: tuple[float, ...]) -> None:
        """Lift from the tile just let go, carry pose, back away."""
        cfg = self.config
        self._report(0.0)
        self._move_arm(dict(zip(cfg.arm_joints, q_above, strict=True)), "lift from the placed tile")
        self._move_arm(self._carry(), "carry pose")
        back = self._pose().compose(Pose2D(-cfg.retreat_distance, 0.0, 0.0))
        self._drive_to(back, "the retreat pose")
        self._report(1.0)

    # ------------------------------------------------------------------ helpers
    def _carry(self) -> dict[str, float]:
        return dict(zip(self.config.arm_joints, self.config.carry_pose, strict=True))

    def _report(self, progress: float) -> None:
        self.feedback(self.phase, max(0.0, min(1.0, progress)), self.hw.map_pose())

    def _check(self) -> None:
        self._check_canceled()
        fault = self.hw.fault()
        if fault:
            self._ride_out(fault, self.hw.fault)

    def _check_canceled(self) -> None:
        if self.hw.canceled():
            self.hw.stop()
            raise MissionFailedError(Outcome.CANCELED, "canceled")

    def _ride_out(self, problem: str, current_problem: Callable[[], str | None]) -> None:
        """Wait, wheels stopped, for a problem to clear; it ends the mission once it lasts
        ``fault_grace``. A device, or this process, that was too busy to report for a moment is no
        broken device: a placement is not given up for it."""
        self.hw.stop()
        deadline = self.hw.now() + self.config.fault_grace
        while problem:
            if self.hw.now() > deadline:
                raise MissionFailedError(Outcome.FAILED_HARDWARE, problem)
            self.hw.sleep(self.config.control_period)
            self._check_canceled()
            problem = current_problem()
        self.log(f"going on: the problem cleared within {self.config.fault_grace:g} s")

    def _fresh(self, read: Callable[[], T | None], problem: str) -> T:
        """What `read` gives; while it gives nothing, the mission rides it out as a fault."""
        found = read()
        if found is None:
            def missing() -> str | None:
                nonlocal found
                found = read()
                return problem if found is None else None

            self._ride_out(problem, missing)
        return found

    def _wait_for_pose(self) -> Pose2D:
        """The first pose, once every device is heard from (they may still be starting up)."""
        deadline = self.hw.now() + self.config.localization_timeout
        while True:
            if self.hw.canceled():
                raise MissionFailedError(Outcome.CANCELED, "canceled")
            pose, fault = self.hw.map_pose(), self.hw.fault()
            if pose is not None and fault is None:
                return pose
            if self.hw.now() > deadline:
                if fault is not None:
                    raise MissionFailedError(Outcome.FAILED_HARDWARE, fault)
                raise MissionFailedError(
                    Outcome.FAILED_NAVIGATION,
                    f"no pose of the base after {self.config.localization_timeout:g} s "
                    "(needs odom and at least one overhead_pose)",
                )
            self.hw.sleep(self.config.control_period)

    def _moved_since(self, pose: Pose2D) -> bool:
        now = self._pose()
        return (now.distance_to(pose) > self.config.settle_distance
                or abs(wrap_angle(now.yaw - pose.yaw)) > self.config.settle_angle)

    def _settled_pose(self) -> Pose2D:
        """The pose once the base stands still: the laser sees the tile from where the base really is,
        and a base still turning at the stop would put the tile centimetres off (5 deg at 0.35 m is 3 cm)."""
        cfg = self.config
        start = self.hw.now()
        still = self._pose()
        still_since = start
        while True:
            self._check()
            self.hw.sleep(cfg.control_period)
            now = self.hw.now()
            if self._moved_since(still):
                still, still_since = self._pose(), now
            elif now - still_since >= cfg.settle_time:
                return still
            if now - start > cfg.settle_timeout:
                self.log(f"the base did not settle within {cfg.settle_timeout:g} s; looking for the tile anyway")
                return self._pose()

    def _pose(self) -> Pose2D:
        return self._fresh(self.hw.map_pose, "lost the base's pose (odometry stopped)")

    def _joints(self) -> Mapping[str, tuple[float, float]]:
        needed = (*self.config.arm_joints, self.config.gripper_joint)

        def complete() -> Mapping[str, tuple[float, float]] | None:
            joints = self.hw.joints()
            return joints if joints is not None and all(n in joints for n in needed) else None

        return self._fresh(complete, "no fresh joint states from the arm")

    def _drive_to(self, goal: Pose2D, what: str, report: bool = True) -> None:
        cfg = self.config
        controller = GoToPose(cfg.navigation)
        start = self._pose()
        initial = max(start.distance_to(goal), 1e-6)
        deadline = self.hw.now() + cfg.navigation_timeout
        while True:
            self._check()
            hazard = self.hw.hazard()
            if hazard:
                self.hw.stop()
                raise MissionFailedError(Outcome.FAILED_NAVIGATION, f"stopped on the way to {what}: {hazard}")
            pose = self._pose()
            linear, angular, done = controller.command(pose, goal)
            if done:
                self.hw.stop()
                return
            if self.hw.now() > deadline:
                self.hw.stop()
                raise MissionFailedError(
                    Outcome.FAILED_NAVIGATION,
                    f"did not reach {what} within {cfg.navigation_timeout:g} s "
                    f"({pose.distance_to(goal) * 100:.0f} cm away)",
                )
            self.hw.drive(linear, angular)
            if report:
                self._report(1.0 - pose.distance_to(goal) / initial)
            self.hw.sleep(cfg.control_period)

    def _move_arm(self, goals: Mapping[str, float], what: str) -> None:
        """Move the arm and wait until it is there. A step the arm does not follow is sent once
        more (a goal can be lost on its way to the servos) before the mission fails."""
        attempts = self.config.arm_attempts
        for attempt in range(1, attempts + 1):
            problem = self._arm_step(goals)
            if problem is None:
                return
            if attempt < attempts:
                self.log(f"the arm did not reach {what} ({problem}); sending the goal again")
        raise MissionFailedError(
            Outcome.FAILED_HARDWARE,
            f"the arm did not reach {what}: {problem} (goal sent {attempts} times)",
        )

    def _arm_step(self, goals: Mapping[str, float]) -> str | None:
        """Send the goals once and wait; None when reached, else what went wrong."""
        cfg = self.config
        joints = self._joints()
        initial = {n: abs(goals[n] - joints[n][0]) for n in goals}
        duration = max(0.3, max(initial.values()) / cfg.arm_speed)
        start = self.hw.now()
        self.hw.move_joints(goals, duration)
        gripper_only = set(goals) == {cfg.gripper_joint}
        moved = False
        while True:
            self._check()
            joints = self._joints()
            errors = {n: abs(goals[n] - joints[n][0]) for n in goals}
            if all(e <= cfg.joint_tolerance for e in errors.values()):
                return None
            now = self.hw.now()
            # a joint that came half a tolerance closer is following the goal
            moved = moved or any(initial[n] - errors[n] > cfg.joint_tolerance / 2 for n in goals)
            stopped = abs(joints[cfg.gripper_joint][1]) < 1e-3
            if gripper_only and moved and stopped and now > start + duration + 0.3:
                return None  # the gripper stopped (holding something, or it cannot open further)
            worst = max(errors, key=errors.get)
            off = f"{worst} is {errors[worst]:.2f} rad off after {now - start:.1f} s"
            if not moved and now - start > cfg.arm_stall_time:
                return f"no joint moved towards the goal; {off}"
            if now - start > duration + cfg.arm_timeout:
                return off
            self.hw.sleep(cfg.control_period)

    def _close_gripper(self) -> float:
        """Close the gripper until it reaches the closed angle or stops on the tile; its angle. A
        close the gripper does not start on is sent once more before the mission fails."""
        attempts = self.config.arm_attempts
        for attempt in range(1, attempts + 1):
            position = self._close_gripper_once()
            if position is not None:
                return position
            if attempt < attempts:
                self.log("the gripper did not start closing; sending the goal again")
        raise MissionFailedError(
            Outcome.FAILED_HARDWARE,
            f"the gripper did not start closing within {self.config.arm_stall_time:g} s "
            f"(goal sent {attempts} times)",
        )

    def _close_gripper_once(self) -> float | None:
        """One close command: the angle where the gripper ends up, None when it never moved."""
        cfg = self.config
        name = cfg.gripper_joint
        start = self._joints()[name][0]
        duration = max(0.3, abs(start - cfg.gripper_closed) / cfg.arm_speed)
        self.hw.move_joints({name: cfg.gripper_closed}, duration)
        sent_at = self.hw.now()
        deadline = sent_at + duration + cfg.arm_timeout
        settle_from = sent_at + 0.3
        still_since: float | None = None
        last = start
        while True:
            self._check()
            position, velocity = self._joints()[name]
            now = self.hw.now()
            if abs(position - cfg.gripper_closed) <= cfg.joint_tolerance:
                return position
            moved = abs(position - start) > cfg.joint_tolerance / 2
            if not moved and now - sent_at > cfg.arm_stall_time:
                return None
            if moved and now > settle_from and abs(velocity) < 1e-3 and abs(position - last) < 0.005:
                still_since = now if still_since is None else still_since
                if now - still_since > 0.25:
                    return position  # stopped on something
            else:
                still_since = None
            last = position
            if now > deadline:
                return position
            self.hw.sleep(cfg.control_period)


class PlaceTileMission(TileMission):
    def __init__(self, hardware: M3Hardware, config: MissionConfig, feedback: Feedback | None = None,
                 log: Callable[[str], None] | None = None) -> None:
        super().__init__(hardware, config, feedback, log, Phase.DRIVING_TO_CACHE)

    def run(self, goal: PlaceGoal) -> MissionResult:
        ended, duration = self._stopping(lambda: self._run(goal))
        if isinstance(ended, MissionFailedError):
            return MissionResult(ended.outcome, ended.message, duration=duration)
        placed, z = ended
        return MissionResult(Outcome.SUCCEEDED, "", placed, z, duration)

    def _run(self, goal: PlaceGoal) -> tuple[Pose2D, float]:
        cfg = self.config
        self.phase = Phase.DRIVING_TO_CACHE
        self._prepare()
        self._approach(goal.cache, cfg.pick_standoff,
                       f"the {goal.tile_type} cache at ({goal.cache[0]:.2f}, {goal.cache[1]:.2f})")

        self.phase = Phase.LOCATING_TILE
        tile = self._locate_tile(goal.footprint, goal.cache, cfg.cache_search_radius, goal.tile_type,
                                 "its cache")

        self.phase = Phase.PICKING
        offset = self._grasp(tile.in_arm, 0.0, goal.height)

        self.phase = Phase.DRIVING_TO_STRUCTURE
        self._approach((goal.pose.x, goal.pose.y), cfg.place_standoff,
                       f"tile {goal.tile_id}'s place at ({goal.pose.x:.2f}, {goal.pose.y:.2f})")

        self.phase = Phase.PLACING
        placed, z, q_above = self._put_down(goal.pose, goal.z, goal.height, goal.footprint, offset, "the goal")
        self.log(f"placed tile {goal.tile_id} at {placed} (goal {goal.pose})")

        self.phase = Phase.RETREATING
        self._retreat(q_above)
        return placed, z
