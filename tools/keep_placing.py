#!/usr/bin/env python3
"""Keep an M3 robot placing tiles, and tell whether its last wheel command was a stop.

    tools/workspace-env python tools/keep_placing.py --pose-file FILE [--namespace /robot1]

A stand-in for the assembly node and the overhead cameras, for tools/signal_trials.py (the set-up
of tests/drivers/test_m3_robot.py): publishes the Create emulator's true pose (`--pose-file`, as
the emulator writes it) on `overhead_pose` and sends `place_tile` goals for tile 3 of paper_14 one
after the other, so that `m3_robot` is always in the middle of a mission. It listens to the
robot's `cmd_vel`; at Ctrl-C or SIGTERM it prints one line, `last cmd_vel: stop`, `last cmd_vel:
moving` or `last cmd_vel: none`. An M3 robot stopped in the middle of a drive must leave `stop`.
"""

from __future__ import annotations

import argparse
import math
import signal
import sys
import time
from pathlib import Path
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped, Twist
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions
from rclpy.time import Time

from tiling_assembly_msgs.action import PlaceTile

CACHE = (0.0, -1.0)  # the long rectangles' parts cache of paper_14
GOAL = (0.0, 0.0, 0.0)  # tile 3 of paper_14: x, y, z (yaw 0)


class Placing(Node):
    def __init__(self, pose_file: Path) -> None:
        super().__init__("keep_placing")
        self.pose_file = pose_file
        self.last_command = "none"
        self.goals_sent = 0
        self.busy = False
        self.overhead = self.create_publisher(PoseStamped, "overhead_pose", qos_profile_sensor_data)
        self.create_subscription(Twist, "cmd_vel", self.on_cmd_vel, 10)
        self.client = ActionClient(self, PlaceTile, "place_tile")
        self.create_timer(0.2, self.publish_true_pose)
        self.create_timer(0.5, self.send_goal_when_idle)

    def on_cmd_vel(self, twist: Twist) -> None:
        self.last_command = "stop" if twist.linear.x == 0.0 and twist.angular.z == 0.0 else "moving"

    def publish_true_pose(self) -> None:
        try:
            x, y, yaw, seen = (float(v) for v in self.pose_file.read_text().split()[:4])
        except (OSError, ValueError):
            return  # not written yet
        pose = PoseStamped()
        pose.header.frame_id = "map"
        now = self.get_clock().now().nanoseconds * 1e-9
        pose.header.stamp = Time(seconds=now - (time.monotonic() - seen)).to_msg()
        pose.pose.position.x, pose.pose.position.y = x, y
        pose.pose.orientation.z, pose.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        self.overhead.publish(pose)

    def send_goal_when_idle(self) -> None:
        if self.busy or not self.client.server_is_ready():
            return
        goal = PlaceTile.Goal()
        goal.tile_id = 3
        goal.tile_type = "long_rectangle"
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x, goal.pose.pose.position.y, goal.pose.pose.position.z = GOAL
        goal.pose.pose.orientation.w = 1.0
        goal.cache.x, goal.cache.y = CACHE
        self.busy = True
        self.goals_sent += 1
        self.client.send_goal_async(goal).add_done_callback(self.on_goal_answered)

    def on_goal_answered(self, future: Any) -> None:
        handle = future.result()
        if not handle.accepted:
            self.busy = False
            return
        handle.get_result_async().add_done_callback(lambda _: setattr(self, "busy", False))


def drain(executor: SingleThreadedExecutor, seconds: float = 1.0) -> None:
    """Take what has arrived before the stop was asked for: the robot's last cmd_vel may still wait
    in the queue on a loaded machine."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="keep_placing", description=__doc__.split("\n\n")[0])
    parser.add_argument("--pose-file", type=Path, required=True, help="the Create emulator's true pose file")
    parser.add_argument("--namespace", default="/robot1", help="the robot's namespace")
    args = parser.parse_args(argv)
    rclpy.init(args=["keep_placing", "--ros-args", "-r", f"__ns:={args.namespace}"],
               signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # both signals: KeyboardInterrupt
    executor = SingleThreadedExecutor()
    node: Placing | None = None
    try:
        node = Placing(args.pose_file)
        executor.add_node(node)
        executor.spin()
    except KeyboardInterrupt:
        drain(executor)
    finally:
        if node is not None:  # else stopped before it started: nothing to tell
            print(f"last cmd_vel: {node.last_command} ({node.goals_sent} goals sent)", flush=True)
            node.destroy_node()
        executor.shutdown()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
