"""A node whose timer callback publishes, sleeps 1 s, publishes again: stopping it at Ctrl-C while
the callback sleeps shows whether callbacks finish before ROS shuts down (tests/test_executor_shutdown.py)."""

from __future__ import annotations

import sys
import time

from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import String

from tiling_ros.spinning import run_node


class SlowCallbackNode(Node):
    def __init__(self) -> None:
        super().__init__("slow_callback_node")
        self.publisher = self.create_publisher(String, "slow_callback", 10)
        self.create_timer(0.2, self.work)

    def work(self) -> None:
        self.publisher.publish(String(data="started"))
        time.sleep(1.0)
        self.publisher.publish(String(data="finished"))


if __name__ == "__main__":
    sys.exit(run_node(SlowCallbackNode, executor=lambda: MultiThreadedExecutor(num_threads=2)))
