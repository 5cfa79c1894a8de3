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
import sys

from geometry_msgs.msg import PoseStamped
from goal_sender import GoalSender, run_until_stopped

from tiling_assembly_msgs.action import NavigateTo


class Navigating(GoalSender):
    def __init__(self, distance: float) -> None:
        super().__init__("keep_navigating", NavigateTo, "navigate_to")
        self.distance = distance

    def publish_overhead_pose(self) -> None:
        pose = PoseStamped()
        pose.header.frame_id = "map"
        pose.header.stamp = self.get_clock().now().to_msg()
        pose.pose.orientation.w = 1.0
        self.overhead.publish(pose)  # the base seems to stay at the origin: it never arrives

    def make_goal(self) -> NavigateTo.Goal:
        goal = NavigateTo.Goal()
        goal.target.header.frame_id = "map"
        goal.target.pose.position.x = self.distance if self.goals_sent % 2 == 0 else 0.0
        goal.target.pose.orientation.w = 1.0
        return goal


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="keep_navigating", description=__doc__.split("\n\n")[0])
    parser.add_argument("--namespace", default="/robot1", help="the navigator's namespace")
    parser.add_argument("--distance", type=float, default=3.0, help="m between the two goals")
    args = parser.parse_args(argv)
    return run_until_stopped("keep_navigating", args.namespace, lambda: Navigating(args.distance))


if __name__ == "__main__":
    sys.exit(main())
