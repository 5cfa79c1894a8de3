#!/usr/bin/env python3
"""Keep a base navigator driving, and tell whether its last wheel command was a stop.

    tools/workspace-env python tools/keep_navigating.py [--namespace /robot1] [--distance 3.0]

A stand-in for the VI explorer and the overhead cameras, for tools/signal_trials.py: publishes the
base's overhead pose (always the map origin, so that the base never arrives) and sends `navigate_to` goals
one after the other, `--distance` m ahead and back, so that the navigator is always in the middle of
a drive. It listens to the navigator's `cmd_vel`; at Ctrl-C or SIGTERM it prints one line, `last
cmd_vel: stop`, `last cmd_vel: moving` or `last cmd_vel: none`. A navigator stopped while driving
must leave `stop`: its wheels would otherwise roll on until the base's watchdog.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped, Twist
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions

from tiling_assembly_msgs.action import NavigateTo


class Navigating(Node):
    def __init__(self, distance: float) -> None:
        super().__init__("keep_navigating")
        self.distance = distance
        self.last_command = "none"
        self.goals_sent = 0
        self.overhead = self.create_publisher(PoseStamped, "overhead_pose", qos_profile_sensor_data)
        self.create_subscription(Twist, "cmd_vel", self.on_cmd_vel, 10)
        self.client = ActionClient(self, NavigateTo, "navigate_to")
        self.create_timer(0.2, self.publish_overhead_pose)
        self.create_timer(0.5, self.send_goal_when_idle)
        self.busy = False

    def on_cmd_vel(self, twist: Twist) -> None:
        self.last_command = "stop" if twist.linear.x == 0.0 and twist.angular.z == 0.0 else "moving"

    def publish_overhead_pose(self) -> None:
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = self.get_clock().now().to_msg()
        pose.pose.orientation.w = 1.0
        self.overhead.publish(pose)  # the base seems to stay at the origin: it never arrives

    def send_goal_when_idle(self) -> None:
        if self.busy or not self.client.server_is_ready():
            return
        goal = NavigateTo.Goal()
        goal.target.header.frame_id = "map"
        goal.target.pose.position.x = self.distance if self.goals_sent % 2 == 0 else 0.0
        goal.target.pose.orientation.w = 1.0
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
    parser = argparse.ArgumentParser(prog="keep_navigating", description=__doc__.split("\n\n")[0])
    parser.add_argument("--namespace", default="/robot1", help="the navigator's namespace")
    parser.add_argument("--distance", type=float, default=3.0, help="m between the two goals")
    args = parser.parse_args(argv)
    rclpy.init(args=["keep_navigating", "--ros-args", "-r", f"__ns:={args.namespace}"],
               signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # both signals: KeyboardInterrupt
    executor = SingleThreadedExecutor()
    node: Navigating | None = None
    try:
        node = Navigating(args.distance)
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
