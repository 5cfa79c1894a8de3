"""What tools/keep_navigating.py and tools/keep_placing.py share: a node that sends one action goal
after the other and remembers whether the last wheel command it heard was a stop, and the process
around it that prints that at Ctrl-C or SIGTERM.

Not run by itself; the two tools import it from their own folder.
"""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from typing import Any

import rclpy
from geometry_msgs.msg import PoseStamped, Twist
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from rclpy.signals import SignalHandlerOptions


class GoalSender(Node):
    """Publishes an overhead pose every 0.2 s, sends `make_goal()` whenever the action server is idle
    (every 0.5 s at most) and records the last `cmd_vel`: `stop`, `moving` or `none`."""

    def __init__(self, name: str, action_type: Any, action_name: str) -> None:
        super().__init__(name)
        self.last_command = "none"
        self.goals_sent = 0
        self.busy = False
        self.overhead = self.create_publisher(PoseStamped, "overhead_pose", qos_profile_sensor_data)
        self.create_subscription(Twist, "cmd_vel", self.on_cmd_vel, 10)
        self.client = ActionClient(self, action_type, action_name)
        self.create_timer(0.2, self.publish_overhead_pose)
        self.create_timer(0.5, self.send_goal_when_idle)

    def publish_overhead_pose(self) -> None:
        """The subclass's overhead pose, or nothing."""

    def make_goal(self) -> Any:
        """The next goal to send."""
        raise NotImplementedError

    def on_cmd_vel(self, twist: Twist) -> None:
        self.last_command = "stop" if twist.linear.x == 0.0 and twist.angular.z == 0.0 else "moving"

    def send_goal_when_idle(self) -> None:
        if self.busy or not self.client.server_is_ready():
            return
        goal = self.make_goal()
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


def run_until_stopped(name: str, namespace: str, make_node: Callable[[], GoalSender]) -> int:
    """Spin `make_node()` in `namespace` until Ctrl-C or SIGTERM, then print its last wheel command."""
    rclpy.init(args=[name, "--ros-args", "-r", f"__ns:={namespace}"],
               signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # both signals: KeyboardInterrupt
    executor = SingleThreadedExecutor()
    node: GoalSender | None = None
    try:
        node = make_node()
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
