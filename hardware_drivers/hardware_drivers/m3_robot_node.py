"""`m3_robot`: serves ``place_tile`` (tiling_assembly_msgs/action/PlaceTile) for one M3 robot by
composing its device nodes (paper section 3.1), in the robot's namespace; and ``remove_tile``
(RemoveTile: take a misplaced tile off the structure, beyond the paper; see remove_tile_mission);
and ``navigate_to`` (NavigateTo: drive the base with nothing to handle, the robot going home when it
has nothing left to place; see drive_mission).

    ros2 run hardware_drivers m3_robot --ros-args -r __ns:=/robot1 \\
        --params-file config/hardware_drivers.yaml --params-file config/crustcrawler_arm.yaml

Composition by topics, not by owning the drivers: the base, the arm and the laser stay separate
processes (``create_base``, ``crustcrawler_arm``, ``hokuyo_urg``), each owning its serial port. On
the real robot that is what a user wants: every device can be started, restarted, watched
(``ros2 topic echo /robot1/scan``) and used alone while this node is down or being debugged; a
crash or a reconnect in one device does not take the others down; and the action semantics do not
depend on serial details, so the simulated robots serve the same actions.

Uses: ``odom`` and ``overhead_pose`` (map pose of base_link from the overhead cameras) to drive
with ``cmd_vel``; ``scan`` to find the tile at its cache or on the structure; ``joint_states`` and
``joint_trajectory`` for the arm; ``bumper``/``wheel_drop`` and ``/diagnostics`` of its own
devices to stop with a clear failure. Tile footprints come from ``/structure`` (latched) or the
``structure_file`` parameter. Feedback carries the action's phases; a failure ends with the
action's error code and one line; a cancel stops the wheels at once. One goal at a time across the
three actions (one arm, one base): a goal of any while another runs is refused, except the same goal sent again
(by a client that missed the goal response), which follows the one under way, with its feedback,
result and cancel, rather than handling the tile twice.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from enum import IntEnum
from typing import Any

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped, Twist
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import JointState, LaserScan
from std_msgs.msg import Bool
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from hardware_drivers.arm_kinematics import ArmGeometry
from hardware_drivers.base_navigation import GoToPoseParams
from hardware_drivers.crustcrawler_arm_node import declare_arm_description
from hardware_drivers.device_health import DeviceHealth, Level
from hardware_drivers.drive_mission import DriveMission
from hardware_drivers.goal_slot import GoalSlot
from hardware_drivers.laser_scan import LaserScanData
from hardware_drivers.map_pose_tracker import MapPoseTracker, set_yaw, yaw_of
from hardware_drivers.node_support import (
    ParameterError,
    device_diagnostics,
    numbers,
    publish_last,
    require,
    require_positive,
    run_node,
)
from hardware_drivers.place_tile_mission import (
    MissionConfig,
    MissionResult,
    Outcome,
    PhaseFeedback,
    PlaceGoal,
    PlaceTileMission,
)
from hardware_drivers.planar_pose import Pose2D
from hardware_drivers.remove_tile_mission import RemovalOutcome, RemovalResult, RemoveGoal, RemoveTileMission
from hardware_drivers.tile_localization import LocalizationParams, footprint_of
from tiling_assembly.messages import structure_from_msg
from tiling_assembly.structure import StructureError, TileType
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import NavigateTo, PlaceTile, RemoveTile
from tiling_assembly_msgs.msg import Structure as StructureMsg
from tiling_ros.parameters import declare_settings, setting
from tiling_ros.qos import DIAGNOSTICS, LATCHED
from tiling_ros.stamps import stamp_to_seconds

DEVICE_NODES = ("create_base", "crustcrawler_arm", "hokuyo_urg")
ARM_JOINTS = ("base_yaw", "shoulder", "elbow", "wrist_pitch", "wrist_roll")
_MISSION = MissionConfig()  # the mission's defaults are this node's


@dataclass(frozen=True)
class M3RobotSettings:
    """The parameters of m3_robot besides the arm's description (config/hardware_drivers.yaml), with
    their defaults: those of the mission (`MissionConfig`)."""

    carry_pose: str = setting("carry", "named arm pose held while driving")
    arm_mount: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        list(_MISSION.arm_mount), "x, y, z (m), yaw (rad) of the arm base in base_link")
    laser_mount: list[float] = setting(  # noqa: RUF009 - a field() with a default_factory
        list(_MISSION.laser_mount), "x, y (m), yaw (rad) of the laser in base_link")
    pick_standoff: float = setting(_MISSION.pick_standoff, "m, base_link to the cache point at the stop")
    place_standoff: float = setting(_MISSION.place_standoff, "m, base_link to the tile goal at the stop")
    preferred_reach: float = setting(_MISSION.preferred_reach, "m from the arm base to a tile to pick")
    reach_tolerance: float = setting(_MISSION.reach_tolerance, "m, accepted deviation from preferred_reach")
    cache_search_radius: float = setting(_MISSION.cache_search_radius, "m around the cache point to look")
    approach_height: float = setting(_MISSION.approach_height, "m above the grasp height before going down")
    arm_speed: float = setting(_MISSION.arm_speed, "rad/s for planned arm moves")
    joint_tolerance: float = setting(_MISSION.joint_tolerance, "rad, a joint counts as arrived this close")
    grasp_margin: float = setting(_MISSION.grasp_margin, "rad, the gripper must stop this far from closed")
    max_linear: float = setting(_MISSION.navigation.max_linear, "m/s, driving speed")
    max_angular: float = setting(_MISSION.navigation.max_angular, "rad/s, turning speed")
    position_tolerance: float = setting(
        _MISSION.navigation.position_tolerance, "m, stop this close to a drive goal")
    yaw_tolerance: float = setting(_MISSION.navigation.yaw_tolerance, "rad, final heading tolerance")
    navigation_timeout: float = setting(_MISSION.navigation_timeout, "s allowed per drive")
    retreat_distance: float = setting(_MISSION.retreat_distance, "m to back away after placing")
    tile_max_rms: float = setting(_MISSION.localization.max_rms, "m, worst accepted fit of a tile's outline")
    device_timeout: float = setting(1.0, "s without odom/joint_states before a device counts as lost")
    overhead_fix_weight: float = setting(0.3, "weight (0..1] of each overhead fix")
    structure_file: str = setting("", "structure file for the tile footprints; empty: use /structure")


# the settings of MissionConfig's lengths, speeds and times, all positive
_POSITIVE = ("pick_standoff", "place_standoff", "preferred_reach", "reach_tolerance", "cache_search_radius",
             "approach_height", "arm_speed", "joint_tolerance", "grasp_margin", "max_linear", "max_angular",
             "position_tolerance", "yaw_tolerance", "navigation_timeout", "retreat_distance", "tile_max_rms")


class M3RobotNode(Node):
    def __init__(self, **node_options) -> None:
        super().__init__("m3_robot", **node_options)
        self.config = self._mission_config()
        require_positive(self.settings, "device_timeout", "overhead_fix_weight")
        self.device_timeout = float(self.settings.device_timeout)
        fix_weight = float(self.settings.overhead_fix_weight)
        require(fix_weight <= 1.0, "overhead_fix_weight must be in (0, 1]")
        structure_file = self.settings.structure_file
        self.tile_types: dict[str, TileType] = {}
        if structure_file:
            try:
                self.tile_types = dict(load_structure(structure_file).tile_types)
            except (StructureError, OSError) as error:
                raise ParameterError(f"structure_file: {error}") from None

        group = ReentrantCallbackGroup()
        self._lock = threading.Lock()
        self.tracker = MapPoseTracker(self, fix_weight, self.device_timeout, group)
        self._joint_state: tuple[float, dict[str, tuple[float, float]]] | None = None
        self._scan: tuple[float, LaserScanData] | None = None
        self._scan_event = threading.Condition(self._lock)
        self._bumper = False
        self._wheel_drop = False
        self._device_status: dict[str, tuple[int, str, dict[str, str]]] = {}
        self.slot = GoalSlot()  # shared by both actions: one arm
        self._goal_run: _GoalRun | None = None  # the latest goal of either action (under way or ended)
        self.stopping = threading.Event()  # the node is stopping: a mission under way ends as canceled
        self.cmd_vel = self.create_publisher(Twist, "cmd_vel", 10)
        self.trajectory = self.create_publisher(JointTrajectory, "joint_trajectory", 10)
        self.create_subscription(LaserScan, "scan", self.on_scan, qos_profile_sensor_data,
                                 callback_group=group)
        self.create_subscription(JointState, "joint_states", self.on_joints, qos_profile_sensor_data,
                                 callback_group=group)
        self.create_subscription(Bool, "bumper", lambda m: setattr(self, "_bumper", m.data), 10,
                                 callback_group=group)
        self.create_subscription(Bool, "wheel_drop", lambda m: setattr(self, "_wheel_drop", m.data), 10,
                                 callback_group=group)
        self.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, DIAGNOSTICS,
                                 callback_group=group)
        self.create_subscription(StructureMsg, "/structure", self.on_structure, LATCHED, callback_group=group)
        self.health = DeviceHealth(on_event=None)
        self.health.set_state(Level.OK, "idle")
        self.diagnostics = device_diagnostics(self, "M3 robot", "m3_robot", self.health.snapshot)
        self.action_server = ActionServer(
            self, PlaceTile, "place_tile", execute_callback=self.execute, goal_callback=self.on_goal,
            cancel_callback=self.on_cancel, callback_group=group,
        )
        self.removal_server = ActionServer(
            self, RemoveTile, "remove_tile", execute_callback=self.execute_removal, goal_callback=self.on_goal,
            cancel_callback=self.on_cancel, callback_group=group,
        )
        self.navigation_server = ActionServer(
            self, NavigateTo, "navigate_to", execute_callback=self.execute_navigation,
            goal_callback=self.on_navigation_goal, cancel_callback=self.on_cancel, callback_group=group,
        )
        self.get_logger().info(
            f"serving {self.resolve_topic_name('place_tile')}, {self.resolve_topic_name('remove_tile')} and "
            f"{self.resolve_topic_name('navigate_to')}; "
            "tile types known: "
            f"{', '.join(sorted(self.tile_types)) or 'none yet (waiting for /structure)'}"
        )

    def _mission_config(self) -> MissionConfig:
        """The mission's parameters: the arm description (crustcrawler_arm.yaml) and this node's."""
        arm = declare_arm_description(self)
        require(all(j in arm["names"] for j in ARM_JOINTS),
                f"joint_names must contain {', '.join(ARM_JOINTS)}")
        settings = self.settings = declare_settings(self, M3RobotSettings)
        carry_name = settings.carry_pose
        require(carry_name in arm["poses"], f"carry_pose '{carry_name}' is not one of named_pose_names")
        geometry = ArmGeometry(
            *arm["links"],
            lower=tuple(arm["lower"][arm["names"].index(j)] for j in ARM_JOINTS),
            upper=tuple(arm["upper"][arm["names"].index(j)] for j in ARM_JOINTS),
        )
        try:
            geometry.validate()
        except ValueError as error:
            raise ParameterError(str(error)) from None
        arm_mount = tuple(numbers(settings, "arm_mount", 4))
        laser_mount = tuple(numbers(settings, "laser_mount", 3))
        require_positive(settings, *_POSITIVE)
        length = {name: float(getattr(settings, name)) for name in _POSITIVE}
        return MissionConfig(
            geometry=geometry,
            arm_joints=ARM_JOINTS,
            gripper_joint=arm["gripper"],
            gripper_open=arm["gripper_open"],
            gripper_closed=arm["gripper_closed"],
            carry_pose=tuple(arm["poses"][carry_name][j] for j in ARM_JOINTS),
            arm_mount=arm_mount,  # type: ignore[arg-type]
            laser_mount=laser_mount,  # type: ignore[arg-type]
            pick_standoff=length["pick_standoff"],
            place_standoff=length["place_standoff"],
            preferred_reach=length["preferred_reach"],
            reach_tolerance=length["reach_tolerance"],
            cache_search_radius=length["cache_search_radius"],
            approach_height=length["approach_height"],
            arm_speed=length["arm_speed"],
            joint_tolerance=length["joint_tolerance"],
            grasp_margin=length["grasp_margin"],
            navigation=GoToPoseParams(
                max_linear=length["max_linear"],
                max_angular=length["max_angular"],
                position_tolerance=length["position_tolerance"],
                yaw_tolerance=length["yaw_tolerance"],
            ),
            navigation_timeout=length["navigation_timeout"],
            retreat_distance=length["retreat_distance"],
            localization=LocalizationParams(max_rms=length["tile_max_rms"]),
        )

    # ------------------------------------------------------------------ inputs
    def on_scan(self, msg: LaserScan) -> None:
        scan = LaserScanData(
            stamp=stamp_to_seconds(msg.header.stamp),
            angle_min=msg.angle_min, angle_increment=msg.angle_increment,
            ranges=np.asarray(msg.ranges, dtype=float), range_min=msg.range_min, range_max=msg.range_max,
            time_increment=msg.time_increment, scan_time=msg.scan_time,
        )
        with self._scan_event:
            self._scan = (time.monotonic(), scan)
            self._scan_event.notify_all()

    def on_joints(self, msg: JointState) -> None:
        velocities = list(msg.velocity) or [0.0] * len(msg.name)
        with self._lock:
            previous = self._joint_state[1] if self._joint_state else {}
            fresh = {n: (p, v) for n, p, v in zip(msg.name, msg.position, velocities, strict=False)}
            merged = {**previous, **fresh}
            self._joint_state = (time.monotonic(), merged)

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        namespace = self.get_namespace().rstrip("/")
        for status in msg.status:
            for device in DEVICE_NODES:
                if status.name.startswith(f"{namespace}/{device}:"):
                    values = {kv.key: kv.value for kv in status.values}
                    with self._lock:
                        self._device_status[device] = (status.level[0] if isinstance(status.level, bytes)
                                                       else int(status.level), status.message, values)

    def on_structure(self, msg: StructureMsg) -> None:
        try:
            structure = structure_from_msg(msg, "/structure")
        except StructureError as error:
            self.get_logger().error(f"ignoring /structure: {error}")
            return
        with self._lock:
            self.tile_types.update(structure.tile_types)
        self.get_logger().info(f"tile types from /structure: {', '.join(sorted(structure.tile_types))}")

    # ------------------------------------------------------------------ M3Hardware for the mission
    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)

    def map_pose(self) -> Pose2D | None:
        return self.tracker.map_pose()

    def drive(self, linear: float, angular: float) -> None:
        twist = Twist()
        twist.linear.x = float(linear)
        twist.angular.z = float(angular)
        self.cmd_vel.publish(twist)

    def stop(self) -> None:
        self.cmd_vel.publish(Twist())

    def scan_after(self, stamp: float, timeout: float) -> LaserScanData | None:
        deadline = time.monotonic() + timeout
        with self._scan_event:
            while self._scan is None or self._scan[0] <= stamp:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._scan_event.wait(remaining)
            return self._scan[1]

    def joints(self) -> Mapping[str, tuple[float, float]] | None:
        with self._lock:
            if self._joint_state is None or time.monotonic() - self._joint_state[0] > self.device_timeout:
                return None
            return dict(self._joint_state[1])

    def move_joints(self, goals: Mapping[str, float], duration: float) -> None:
        msg = JointTrajectory()
        msg.joint_names = list(goals)
        point = JointTrajectoryPoint()
        point.positions = [float(v) for v in goals.values()]
        point.time_from_start.sec = int(duration)
        point.time_from_start.nanosec = int((duration - int(duration)) * 1e9)
        msg.points = [point]
        self.trajectory.publish(msg)

    def hazard(self) -> str | None:
        if self._wheel_drop:
            return "a wheel dropped"
        if self._bumper:
            return "the bumper is pressed"
        return None

    def fault(self) -> str | None:
        now = time.monotonic()
        odom_age = self.tracker.odom_age()
        with self._lock:
            joints_age = now - self._joint_state[0] if self._joint_state else math.inf
            statuses = dict(self._device_status)
        for device in ("create_base", "crustcrawler_arm"):
            status = statuses.get(device)
            if status and status[2].get("connected") == "false":
                return f"{device}: {status[1]}"
        arm = statuses.get("crustcrawler_arm")
        if arm and arm[0] == Level.ERROR:
            return f"crustcrawler_arm: {arm[1]}"
        if odom_age > self.device_timeout:
            return f"create_base: no odom for {self.device_timeout:g} s (base not answering?)"
        if joints_age > self.device_timeout:
            return f"crustcrawler_arm: no joint_states for {self.device_timeout:g} s (arm not answering?)"
        return None

    # ------------------------------------------------------------------ the actions
    def on_goal(self, goal: PlaceTile.Goal | RemoveTile.Goal) -> GoalResponse:
        """Either action's goal: one at a time across both (a robot has one arm)."""
        with self._lock:
            latest = self._goal_run
            if latest is not None and not latest.done.is_set() and latest.request == goal:
                latest.joins.append(time.monotonic())
                return GoalResponse.ACCEPT  # sent again by a client that missed the goal response
        if not self.slot.reserve():
            busy = f"{latest.what} is under way" if latest is not None and not latest.done.is_set() \
                else "another goal was just accepted"
            self.get_logger().warning(f"{_kind_of(goal).name} goal for tile {goal.tile_id} rejected: {busy} "
                                      "(one arm, one goal at a time)")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def on_navigation_goal(self, goal: NavigateTo.Goal) -> GoalResponse:
        if not self.slot.reserve():
            self.get_logger().warning("navigate_to goal rejected: another goal is under way (one base, one goal "
                                      "at a time)")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def on_cancel(self, goal_handle) -> CancelResponse:
        self.stop()  # at once; the mission notices the request within one control period
        return CancelResponse.ACCEPT

    def execute(self, goal_handle) -> PlaceTile.Result:
        return self._serve(goal_handle, self._place)

    def execute_removal(self, goal_handle) -> RemoveTile.Result:
        return self._serve(goal_handle, self._remove)

    def execute_navigation(self, goal_handle) -> NavigateTo.Result:
        with self._lock:
            started = self.slot.start()
        if not started:
            goal_handle.abort()
            return NavigateTo.Result(success=False, message="another goal is under way")
        try:
            ended = self._navigation(goal_handle)
        finally:
            with self._lock:
                self.slot.finish()
        result = NavigateTo.Result(success=ended.outcome == Outcome.SUCCEEDED, message=ended.message)
        self._fill_pose(result.final_pose, ended.placed_pose, 0.0)
        if result.success:
            goal_handle.succeed()
            self.health.set_state(Level.OK, "idle; drove to the goal")
            self.get_logger().info(f"drove to the goal in {ended.duration:.1f} s")
        elif ended.outcome == Outcome.CANCELED and goal_handle.is_cancel_requested:
            goal_handle.canceled()
            self.health.set_state(Level.OK, "idle; drive canceled")
        else:
            goal_handle.abort()
            self.health.set_state(Level.WARN, f"idle; drive failed: {ended.message}")
            self.get_logger().error(f"drive failed ({ended.outcome.name}): {ended.message}")
        return result

    def _navigation(self, goal_handle) -> MissionResult:
        request: NavigateTo.Goal = goal_handle.request
        problem = _frame_problem(request.target.header.frame_id)
        if problem:
            return MissionResult(Outcome.FAILED_NAVIGATION, problem)
        goal = _pose_of(request.target)
        tolerances = {name: float(value) for name, value in (("position_tolerance", request.position_tolerance),
                                                              ("yaw_tolerance", request.yaw_tolerance)) if value > 0}
        config = replace(self.config, navigation=replace(self.config.navigation, **tolerances))
        self.get_logger().info(f"driving to {goal}")

        def publish(_phase: IntEnum, _progress: float, pose: Pose2D | None) -> None:
            feedback = NavigateTo.Feedback(distance_remaining=pose.distance_to(goal) if pose is not None else 0.0)
            self._fill_pose(feedback.current_pose, pose, 0.0)
            goal_handle.publish_feedback(feedback)
            self.health.set_state(Level.OK, f"driving to {goal}")

        mission = DriveMission(_GoalHardware(self, goal_handle, _GoalRun(request)), config, publish,
                               log=self.get_logger().info)
        return mission.run(goal, f"the goal at ({goal.x:.2f}, {goal.y:.2f})")

    def _serve(self, goal_handle, run: Callable[[Any, _GoalRun], Any]) -> Any:
        """Run a goal of either action, or have it follow the same goal under way; its result."""
        request = goal_handle.request
        kind = _kind_of(request)
        current = _GoalRun(request)
        with self._lock:  # the slot and the latest goal change together: a goal sent again finds it
            latest = self._goal_run
            joining = latest is not None and latest.claim_join(request, time.monotonic(), self.slot.start_grace)
            started = not joining and self.slot.start()
            if started:
                self._goal_run = current
        if joining:
            return self._follow(goal_handle, request, latest)
        if not started:  # a second mission would drive the same robot at the same time
            goal_handle.abort()
            return kind.action.Result(error_code=kind.busy_code, message="another goal is under way")
        result = kind.action.Result(error_code=kind.action.Result.FAILED_HARDWARE,
                                    message=f"{current.what} ended in an internal error")
        try:
            result = run(goal_handle, current)
        finally:
            with self._lock:
                self.slot.finish()
            current.finish(result)
        self._conclude(goal_handle, request, result)
        return result

    def _follow(self, goal_handle, request, latest: _GoalRun) -> Any:
        """The same goal sent again while it runs (its client missed the goal response): it gets
        that goal's feedback and result, and can cancel it; the tile is not handled a second time."""
        self.get_logger().warning(f"{latest.what}: the same goal again (its client missed the goal "
                                  "response?); it follows the one under way")
        latest.followers.append(goal_handle)
        latest.done.wait()
        self._conclude(goal_handle, request, latest.result, quiet=True)
        return latest.result

    def _conclude(self, goal_handle, request, result, quiet: bool = False) -> None:
        """End the goal as its mission ended; `quiet` for a goal that followed another (told once)."""
        kind = _kind_of(request)
        tile = request.tile_id
        if result.error_code == kind.action.Result.SUCCEEDED:
            goal_handle.succeed()
            if not quiet:
                self.health.set_state(Level.OK, f"idle; {kind.done} tile {tile}")
                self.get_logger().info(f"{kind.done} tile {tile} in {result.duration:.1f} s")
        elif result.error_code == kind.action.Result.CANCELED:
            # canceled by this goal's client, by a goal that followed it, or by the node stopping
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
            else:
                goal_handle.abort()
            if not quiet:
                self.health.set_state(Level.OK, f"idle; {_what(request)} canceled")
                self.get_logger().info(f"{_what(request)}: canceled, wheels stopped")
        else:
            goal_handle.abort()
            if not quiet:
                code = kind.outcome(result.error_code).name
                self.health.set_state(Level.WARN, f"idle; {_what(request)} failed: {result.message}")
                self.get_logger().error(f"{_what(request)} failed ({code}): {result.message}")

    def _place(self, goal_handle, current: _GoalRun) -> PlaceTile.Result:
        ended = self._placement(goal_handle, current)
        result = PlaceTile.Result(error_code=int(ended.outcome), message=ended.message, duration=float(ended.duration))
        self._fill_pose(result.placed_pose, ended.placed_pose, ended.placed_z)
        return result

    def _placement(self, goal_handle, current: _GoalRun) -> MissionResult:
        request: PlaceTile.Goal = goal_handle.request
        shape = self._shape(request.tile_type)
        if shape is None:
            return MissionResult(Outcome.FAILED_NO_TILE, _unknown_type(request.tile_type))
        problem = _frame_problem(request.pose.header.frame_id)
        if problem:
            return MissionResult(Outcome.FAILED_NAVIGATION, problem)
        goal = PlaceGoal(
            tile_id=request.tile_id, tile_type=request.tile_type, footprint=shape[0], height=shape[1],
            pose=_pose_of(request.pose), z=request.pose.pose.position.z, cache=(request.cache.x, request.cache.y),
        )
        self.get_logger().info(
            f"placing tile {goal.tile_id} ({goal.tile_type}) at {goal.pose}, z {goal.z:.3f} m; "
            f"cache at ({goal.cache[0]:.2f}, {goal.cache[1]:.2f})"
        )
        feedback = self._feedback(PlaceTile.Feedback, goal_handle, current)
        mission = PlaceTileMission(_GoalHardware(self, goal_handle, current), self.config, feedback,
                                   log=self.get_logger().info)
        return mission.run(goal)

    def _remove(self, goal_handle, current: _GoalRun) -> RemoveTile.Result:
        ended = self._removal(goal_handle, current)
        result = RemoveTile.Result(error_code=int(ended.outcome), message=ended.message,
                                   duration=float(ended.duration))
        self._fill_pose(result.found_pose, ended.found_pose, ended.found_z)
        return result

    def _removal(self, goal_handle, current: _GoalRun) -> RemovalResult:
        request: RemoveTile.Goal = goal_handle.request
        shape = self._shape(request.tile_type)
        if shape is None:
            return RemovalResult(RemovalOutcome.FAILED_NOT_FOUND, _unknown_type(request.tile_type))
        problem = _frame_problem(request.pose.header.frame_id)
        if problem:
            return RemovalResult(RemovalOutcome.FAILED_NAVIGATION, problem)
        drop = request.drop_off
        goal = RemoveGoal(
            tile_id=request.tile_id, tile_type=request.tile_type, footprint=shape[0], height=shape[1],
            pose=_pose_of(request.pose), z=request.pose.pose.position.z, drop_off=(drop.x, drop.y, drop.z),
        )
        self.get_logger().info(
            f"removing tile {goal.tile_id} ({goal.tile_type}) believed at {goal.pose}, z {goal.z:.3f} m; "
            f"drop-off at ({drop.x:.2f}, {drop.y:.2f})"
        )
        feedback = self._feedback(RemoveTile.Feedback, goal_handle, current)
        mission = RemoveTileMission(_GoalHardware(self, goal_handle, current), self.config, feedback,
                                    log=self.get_logger().info)
        return mission.run(goal)

    def _shape(self, tile_type: str) -> tuple[np.ndarray, float] | None:
        """The tile type's footprint and height, None when no structure named it."""
        with self._lock:
            known = self.tile_types.get(tile_type)
        if known is None:
            return None
        vertices = known.shape.vertices
        return footprint_of(known), float(vertices[:, 2].max() - vertices[:, 2].min())

    def _feedback(self, feedback_type, goal_handle, current: _GoalRun) -> PhaseFeedback:
        """Publishes a mission's phase to its goal and the goals that follow it."""
        what = _what(goal_handle.request)

        def publish(phase: IntEnum, progress: float, pose: Pose2D | None) -> None:
            msg = feedback_type()
            msg.phase = int(phase)
            msg.phase_progress = float(progress)
            self._fill_pose(msg.robot_pose, pose, 0.0)
            for handle in (goal_handle, *current.followers):
                handle.publish_feedback(msg)
            self.health.set_state(Level.OK, f"{what}: {phase.name.lower()} ({progress:.0%})")

        return publish

    def _fill_pose(self, msg: PoseStamped, pose: Pose2D | None, z: float) -> None:
        msg.header.frame_id = "map"
        msg.header.stamp = self.get_clock().now().to_msg()
        if pose is not None:
            msg.pose.position.x, msg.pose.position.y, msg.pose.position.z = pose.x, pose.y, float(z)
            set_yaw(msg.pose.orientation, pose.yaw)


@dataclass(frozen=True)
class _Kind:
    """What differs between the node's two actions."""

    action: Any  # PlaceTile or RemoveTile
    name: str
    noun: str
    done: str
    outcome: type[IntEnum]  # the mission's result codes
    busy_code: int  # the result of a goal that starts while another runs


_PLACING = _Kind(PlaceTile, "place_tile", "placement", "placed", Outcome, PlaceTile.Result.FAILED_PRECONDITION)
_REMOVING = _Kind(RemoveTile, "remove_tile", "removal", "removed", RemovalOutcome, RemoveTile.Result.FAILED_HARDWARE)


def _kind_of(request: PlaceTile.Goal | RemoveTile.Goal) -> _Kind:
    return _REMOVING if isinstance(request, RemoveTile.Goal) else _PLACING


def _what(request: PlaceTile.Goal | RemoveTile.Goal) -> str:
    return f"tile {request.tile_id}'s {_kind_of(request).noun}"


def _unknown_type(tile_type: str) -> str:
    return f"unknown tile type '{tile_type}' (no footprint from /structure or structure_file)"


def _frame_problem(frame: str) -> str | None:
    if frame in ("", "map"):
        return None
    return f"goal pose in frame '{frame}'; this robot drives in 'map'"


def _pose_of(msg: PoseStamped) -> Pose2D:
    return Pose2D(msg.pose.position.x, msg.pose.position.y, yaw_of(msg.pose.orientation))


@dataclass
class _GoalRun:
    """The goal under way (of either action): its request, the goals that sent it again, and how
    it ended."""

    request: PlaceTile.Goal | RemoveTile.Goal
    followers: list = field(default_factory=list)  # goal handles of the goals that sent it again
    joins: list[float] = field(default_factory=list)  # when such goals were accepted (not started yet)
    done: threading.Event = field(default_factory=threading.Event)
    result: Any = None  # the action's Result, once done

    @property
    def what(self) -> str:
        return _what(self.request)

    def claim_join(self, request: PlaceTile.Goal | RemoveTile.Goal, now: float, grace: float) -> bool:
        """Whether a goal starting now was accepted to join this one (counted once); an
        acceptance whose goal did not start within `grace` s lapses (its response was lost too)."""
        self.joins = [t for t in self.joins if now - t < grace]
        if not self.joins or request != self.request:
            return False
        self.joins.pop(0)
        return True

    def finish(self, result: Any) -> None:
        self.result = result
        self.done.set()


class _GoalHardware:
    """The node's robot interface, with cancellation bound to one goal (and the goals that sent it
    again)."""

    def __init__(self, node: M3RobotNode, goal_handle, current: _GoalRun) -> None:
        self._node = node
        self._goal_handle = goal_handle
        self._current = current

    def canceled(self) -> bool:
        handles = (self._goal_handle, *self._current.followers)
        return any(bool(h.is_cancel_requested) for h in handles) or self._node.stopping.is_set()

    def __getattr__(self, name: str):
        return getattr(self._node, name)


def main() -> int:
    return run_node(M3RobotNode, executor=lambda: MultiThreadedExecutor(num_threads=4),
                    on_stop=lambda node: node.stopping.set(),
                    on_shutdown=lambda node: publish_last(node.cmd_vel, Twist()) if node.context.ok() else None)


if __name__ == "__main__":
    raise SystemExit(main())
