"""`base_navigator`: serves ``navigate_to`` (tiling_assembly_msgs/action/NavigateTo) for a Create
base, in the robot's namespace: the scanning robot's viewpoints (paper section 2.2).

    ros2 run hardware_drivers base_navigator --ros-args -r __ns:=/vi

Drives with ``cmd_vel`` from ``odom`` corrected by ``overhead_pose`` (rotate, drive, rotate; see
``base_navigation``). Feedback: the current pose and the distance left. Fails with one line when
there is no pose, the bumper is pressed, a wheel drops or the goal is not reached in time; a
cancel stops the wheels at once. (The M3 robots drive inside ``m3_robot``; do not run both on one
base, they would both command ``cmd_vel``.)
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

from geometry_msgs.msg import Twist
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Bool

from hardware_drivers.base_navigation import GoToPose, GoToPoseParams
from hardware_drivers.goal_slot import GoalSlot
from hardware_drivers.map_pose_tracker import MapPoseTracker, set_yaw, yaw_of
from hardware_drivers.node_support import publish_last, require, require_positive, run_node
from hardware_drivers.planar_pose import Pose2D
from tiling_assembly_msgs.action import NavigateTo
from tiling_ros.parameters import declare_settings, setting

_DRIVE = GoToPoseParams()


@dataclass(frozen=True)
class BaseNavigatorSettings:
    """The parameters of base_navigator (config/hardware_drivers.yaml), with their defaults."""

    max_linear: float = setting(_DRIVE.max_linear, "m/s, driving speed")
    max_angular: float = setting(_DRIVE.max_angular, "rad/s, turning speed")
    position_tolerance: float = setting(0.02, "m, default goal tolerance")
    yaw_tolerance: float = setting(0.05, "rad, default heading tolerance")
    navigation_timeout: float = setting(120.0, "s allowed per goal")
    control_rate: float = setting(20.0, "Hz, control loop")
    overhead_fix_weight: float = setting(0.3, "weight (0..1] of each overhead fix")
    device_timeout: float = setting(1.0, "s without odom before the base counts as lost")
    map_frame: str = setting("map", "frame of goals and overhead fixes")


class BaseNavigatorNode(Node):
    def __init__(self, **node_options) -> None:
        super().__init__("base_navigator", **node_options)
        settings = self.settings = declare_settings(self, BaseNavigatorSettings)
        require_positive(settings, "max_linear", "max_angular", "position_tolerance", "yaw_tolerance",
                         "navigation_timeout", "control_rate", "overhead_fix_weight", "device_timeout")
        self.params = GoToPoseParams(
            max_linear=float(settings.max_linear),
            max_angular=float(settings.max_angular),
            position_tolerance=float(settings.position_tolerance),
            yaw_tolerance=float(settings.yaw_tolerance),
        )
        self.timeout = float(settings.navigation_timeout)
        self.rate = float(settings.control_rate)
        fix_weight = float(settings.overhead_fix_weight)
        odom_timeout = float(settings.device_timeout)
        require(fix_weight <= 1.0, "overhead_fix_weight must be in (0, 1]")
        self.frame = settings.map_frame
        group = ReentrantCallbackGroup()
        self.tracker = MapPoseTracker(self, fix_weight, odom_timeout, group)
        self.hazards = {"bumper": False, "wheel_drop": False}
        for name in self.hazards:
            self.create_subscription(Bool, name, lambda m, n=name: self.hazards.__setitem__(n, m.data), 10,
                                     callback_group=group)
        self.cmd_vel = self.create_publisher(Twist, "cmd_vel", 10)
        self.slot = GoalSlot()
        self.stopping = threading.Event()  # the node is stopping: a drive under way ends, wheels stopped
        self.server = ActionServer(self, NavigateTo, "navigate_to", execute_callback=self.execute,
                                   goal_callback=self.on_goal, cancel_callback=self.on_cancel,
                                   callback_group=group)

    def on_goal(self, goal: NavigateTo.Goal) -> GoalResponse:
        frame = goal.target.header.frame_id
        if frame not in ("", self.frame):
            self.get_logger().error(f"navigate_to goal in frame '{frame}' rejected (expected '{self.frame}')")
            return GoalResponse.REJECT
        if not self.slot.reserve():
            self.get_logger().warning("navigate_to goal rejected: already driving to another goal")
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    def on_cancel(self, goal_handle) -> CancelResponse:
        self.cmd_vel.publish(Twist())
        return CancelResponse.ACCEPT

    def execute(self, goal_handle) -> NavigateTo.Result:
        if not self.slot.start():
            goal_handle.abort()
            return NavigateTo.Result(success=False, message="already driving to another goal")
        try:
            success, message = self._drive(goal_handle)
        finally:
            self.cmd_vel.publish(Twist())
            self.slot.finish()
        result = NavigateTo.Result(success=success, message=message)
        result.final_pose.header.frame_id = self.frame
        result.final_pose.header.stamp = self.get_clock().now().to_msg()
        pose = self.tracker.map_pose()
        if pose is not None:
            result.final_pose.pose.position.x, result.final_pose.pose.position.y = pose.x, pose.y
            set_yaw(result.final_pose.pose.orientation, pose.yaw)
        if success:
            goal_handle.succeed()
        elif goal_handle.is_cancel_requested:
            goal_handle.canceled()
        else:
            goal_handle.abort()
            self.get_logger().error(f"navigate_to failed: {message}")
        return result

    def _drive(self, goal_handle) -> tuple[bool, str]:
        request: NavigateTo.Goal = goal_handle.request
        target = Pose2D(request.target.pose.position.x, request.target.pose.position.y,
                        yaw_of(request.target.pose.orientation))
        params = GoToPoseParams(**{
            **self.params.__dict__,
            **({"position_tolerance": request.position_tolerance} if request.position_tolerance > 0 else {}),
            **({"yaw_tolerance": request.yaw_tolerance} if request.yaw_tolerance > 0 else {}),
        })
        controller = GoToPose(params)
        deadline = time.monotonic() + self.timeout
        period = 1.0 / self.rate
        while True:
            if goal_handle.is_cancel_requested:
                return False, "canceled"
            if self.stopping.is_set():
                return False, "the navigator is shutting down"
            pose = self.tracker.map_pose()
            if pose is None:
                return False, "no pose of the base (needs odom and at least one overhead_pose)"
            if self.hazards["wheel_drop"] or self.hazards["bumper"]:
                cause = "a wheel dropped" if self.hazards["wheel_drop"] else "the bumper is pressed"
                return False, f"stopped: {cause}"
            linear, angular, done = controller.command(pose, target)
            if done:
                return True, ""
            if time.monotonic() > deadline:
                away = pose.distance_to(target)
                return False, f"goal not reached within {self.timeout:g} s ({away:.2f} m away)"
            twist = Twist()
            twist.linear.x, twist.angular.z = linear, angular
            self.cmd_vel.publish(twist)
            feedback = NavigateTo.Feedback()
            feedback.current_pose.header.frame_id = self.frame
            feedback.current_pose.header.stamp = self.get_clock().now().to_msg()
            feedback.current_pose.pose.position.x, feedback.current_pose.pose.position.y = pose.x, pose.y
            set_yaw(feedback.current_pose.pose.orientation, pose.yaw)
            feedback.distance_remaining = float(pose.distance_to(target))
            goal_handle.publish_feedback(feedback)
            time.sleep(period)


def main() -> int:
    return run_node(BaseNavigatorNode, executor=lambda: MultiThreadedExecutor(num_threads=3),
                    on_stop=lambda node: node.stopping.set(),
                    on_shutdown=lambda node: publish_last(node.cmd_vel, Twist()) if node.context.ok() else None)


if __name__ == "__main__":
    raise SystemExit(main())
