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
import sys
import time
from pathlib import Path

from geometry_msgs.msg import PoseStamped
from goal_sender import GoalSender, run_until_stopped
from rclpy.time import Time

from tiling_assembly_msgs.action import PlaceTile

CACHE = (0.0, -1.0)  # the long rectangles' parts cache of paper_14
GOAL = (0.0, 0.0, 0.0)  # tile 3 of paper_14: x, y, z (yaw 0)


class Placing(GoalSender):
    def __init__(self, pose_file: Path) -> None:
        super().__init__("keep_placing", PlaceTile, "place_tile")
        self.pose_file = pose_file

    def publish_overhead_pose(self) -> None:
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

    def make_goal(self) -> PlaceTile.Goal:
        goal = PlaceTile.Goal()
        goal.tile_id = 3
        goal.tile_type = "long_rectangle"
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x, goal.pose.pose.position.y, goal.pose.pose.position.z = GOAL
        goal.pose.pose.orientation.w = 1.0
        goal.cache.x, goal.cache.y = CACHE
        return goal


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="keep_placing", description=__doc__.split("\n\n")[0])
    parser.add_argument("--pose-file", type=Path, required=True, help="the Create emulator's true pose file")
    parser.add_argument("--namespace", default="/robot1", help="the robot's namespace")
    args = parser.parse_args(argv)
    return run_until_stopped("keep_placing", args.namespace, lambda: Placing(args.pose_file))


if __name__ == "__main__":
    sys.exit(main())
