"""The viewpoints VI robots claim, exchanged between their explorers (several scanning robots, the
paper's N_s; how the claims divide the work: `exploration`).

Each explorer publishes the viewpoint it drives to on `next_viewpoint` in its own namespace
(geometry_msgs/PoseStamped, map, latched) and follows every other `/<robot>/next_viewpoint` that
appears in the graph (a robot may start late). A claim stands until its robot claims another, or
for `max_age` s of the node's clock (a robot that died, or whose link is down, holds nothing).
"""

from __future__ import annotations

import math
from typing import Any

from geometry_msgs.msg import PoseStamped
from rclpy.node import Node

from tiling_assembly.geometry import (
    quaternion_from_rotation,
    rotation_from_quaternion,
    rotation_from_rpy,
    rpy_from_rotation,
)
from tiling_ros.qos import LATCHED
from tiling_ros.stamps import stamp_from_seconds, stamp_to_seconds

TOPIC = "next_viewpoint"
Pose2 = tuple[float, float, float]


class ViewpointClaims:
    def __init__(self, node: Node, max_age: float) -> None:
        self.node = node
        self.max_age = max_age
        self.publisher = node.create_publisher(PoseStamped, TOPIC, LATCHED)
        self.own_topic = node.resolve_topic_name(TOPIC)
        self.subscriptions: dict[str, Any] = {}
        self.claims: dict[str, tuple[float, Pose2]] = {}  # topic -> (stamp s, pose)

    def claim(self, pose: Pose2, now: float) -> None:
        """Tell the others this robot drives to `pose` (x, y, yaw) at `now` (s)."""
        msg = PoseStamped()
        msg.header.frame_id = "map"
        msg.header.stamp = stamp_from_seconds(now)
        msg.pose.position.x, msg.pose.position.y = pose[0], pose[1]
        o = msg.pose.orientation
        o.x, o.y, o.z, o.w = quaternion_from_rotation(rotation_from_rpy(0.0, 0.0, pose[2]))
        self.publisher.publish(msg)

    def follow(self) -> None:
        """Subscribe the other explorers' claims not yet followed (call now and then)."""
        for topic, _types in self.node.get_topic_names_and_types():
            if topic.endswith(f"/{TOPIC}") and topic != self.own_topic and topic not in self.subscriptions:
                self.subscriptions[topic] = self.node.create_subscription(
                    PoseStamped, topic, lambda msg, topic=topic: self._heard(topic, msg), LATCHED)

    def robots(self) -> list[str]:
        """The other VI robots (those whose explorer claims viewpoints), claimed yet or not."""
        return [topic.split("/")[1] for topic in self.subscriptions]

    def current(self, now: float) -> list[Pose2]:
        """The other robots' claims that still stand at `now` (s)."""
        return [pose for stamp, pose in self.claims.values() if now - stamp <= self.max_age]

    def _heard(self, topic: str, msg: PoseStamped) -> None:
        o, p = msg.pose.orientation, msg.pose.position
        if not all(math.isfinite(v) for v in (p.x, p.y, o.x, o.y, o.z, o.w)) or o.x == o.y == o.z == o.w == 0.0:
            self.node.get_logger().warn(f"ignored a viewpoint claim on {topic}: not a pose", throttle_duration_sec=10.0)
            return
        yaw = rpy_from_rotation(rotation_from_quaternion(o.x, o.y, o.z, o.w))[2]
        self.claims[topic] = (stamp_to_seconds(msg.header.stamp), (p.x, p.y, yaw))
