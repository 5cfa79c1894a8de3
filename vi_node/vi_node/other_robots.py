"""The other robots' overhead poses, followed from a node of the VI robot (beyond paper section
2.2.1: the overhead cameras localize every robot, and a robot beside the structure hides part of it).

Every robot's pose comes on `/<robot>/overhead_pose` (geometry_msgs/PoseStamped, map). The robots
followed are those named, or, when none is named, every one whose topic appears in the graph (a
team can grow while the VI robot runs), besides this robot's own. The poses go to `on_pose` by
robot name; a pose with a zero quaternion is refused with a one-line complaint to `on_bad_pose`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from geometry_msgs.msg import PoseStamped
from rclpy.node import Node

from tiling_ros.qos import OTHER_ROBOT_POSES
from tiling_ros.stamps import stamp_to_nanoseconds
from vi_node.pose_prior import OverheadPose

PoseSink = Callable[[str, int, OverheadPose], None]  # robot, stamp (ns), pose


class OtherRobots:
    def __init__(self, node: Node, names: str, on_pose: PoseSink, on_bad_pose: Callable[[str], None]) -> None:
        self.node = node
        self.names = [n.strip() for n in names.split(",") if n.strip()]
        self.on_pose = on_pose
        self.on_bad_pose = on_bad_pose
        self.subscriptions: dict[str, Any] = {}

    def follow(self) -> None:
        """Subscribe the robots not yet followed (call now and then: robots appear late)."""
        for name in self.names or self._in_graph():
            if name not in self.subscriptions:
                self.subscriptions[name] = self.node.create_subscription(
                    PoseStamped, f"/{name}/overhead_pose", lambda msg, name=name: self._heard(name, msg),
                    OTHER_ROBOT_POSES,
                )

    def _in_graph(self) -> list[str]:
        own = self.node.resolve_topic_name("overhead_pose")
        return [topic.split("/")[1] for topic, _ in self.node.get_topic_names_and_types()
                if topic.endswith("/overhead_pose") and topic.count("/") == 2 and topic != own]

    def _heard(self, name: str, msg: PoseStamped) -> None:
        p, q = msg.pose.position, msg.pose.orientation
        try:
            pose = OverheadPose.from_quaternion(p.x, p.y, q.x, q.y, q.z, q.w)
        except ValueError:
            self.on_bad_pose(f"ignored an overhead pose of {name} with a zero quaternion")
            return
        self.on_pose(name, stamp_to_nanoseconds(msg.header.stamp), pose)
