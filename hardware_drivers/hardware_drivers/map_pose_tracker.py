"""The map pose of a robot base on the ROS side: ``odom`` corrected by ``overhead_pose`` fixes
(see ``base_navigation.PoseFusion``), shared by ``m3_robot`` and ``base_navigator``."""

from __future__ import annotations

import math
import threading
import time
from collections import deque

from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.callback_groups import CallbackGroup
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data

from hardware_drivers.base_navigation import PoseFusion
from hardware_drivers.planar_pose import Pose2D
from tiling_ros.stamps import stamp_to_seconds


def yaw_of(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def set_yaw(q, yaw: float) -> None:
    q.x = q.y = 0.0
    q.z = math.sin(yaw / 2.0)
    q.w = math.cos(yaw / 2.0)


class MapPoseTracker:
    """Subscribes ``odom`` and ``overhead_pose`` (frame ``map``) of the node's namespace."""

    def __init__(self, node: Node, fix_weight: float, odom_timeout: float,
                 callback_group: CallbackGroup | None = None) -> None:
        self.node = node
        self.odom_timeout = odom_timeout
        self.fusion = PoseFusion(fix_weight)
        self._history: deque[tuple[float, Pose2D]] = deque(maxlen=200)  # (header stamp s, odom pose)
        self._lock = threading.Lock()
        self.odom_time = -math.inf  # time.monotonic() of the last odom
        node.create_subscription(Odometry, "odom", self._on_odom, qos_profile_sensor_data,
                                 callback_group=callback_group)
        node.create_subscription(PoseStamped, "overhead_pose", self._on_fix, qos_profile_sensor_data,
                                 callback_group=callback_group)

    def _on_odom(self, msg: Odometry) -> None:
        pose = Pose2D(msg.pose.pose.position.x, msg.pose.pose.position.y, yaw_of(msg.pose.pose.orientation))
        stamp = stamp_to_seconds(msg.header.stamp)
        with self._lock:
            self.fusion.update_odometry(pose)
            self._history.append((stamp, pose))
            self.odom_time = time.monotonic()

    def _on_fix(self, msg: PoseStamped) -> None:
        if msg.header.frame_id not in ("", "map"):
            self.node.get_logger().warning(
                f"overhead_pose in frame '{msg.header.frame_id}' ignored (expected 'map')",
                throttle_duration_sec=10.0,
            )
            return
        pose = Pose2D(msg.pose.position.x, msg.pose.position.y, yaw_of(msg.pose.orientation))
        stamp = stamp_to_seconds(msg.header.stamp)
        with self._lock:
            # the camera saw the base where odometry put it at the image's time, not now
            self.fusion.update_fix(pose, self._odometry_at(stamp))

    def _odometry_at(self, stamp: float) -> Pose2D | None:
        if not self._history or stamp <= 0.0:
            return None
        return min(self._history, key=lambda item: abs(item[0] - stamp))[1]

    def odom_age(self) -> float:
        with self._lock:
            return time.monotonic() - self.odom_time

    def map_pose(self) -> Pose2D | None:
        """The base's map pose; None before the first fix or when odometry stopped."""
        with self._lock:
            if not self.fusion.ready or time.monotonic() - self.odom_time > self.odom_timeout:
                return None
            return self.fusion.map_pose()
