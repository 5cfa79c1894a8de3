"""A node whose destruction never returns, as a DDS participant's deletion now and then does: stopping
it at Ctrl-C shows that the process still ends (tests/test_executor_shutdown.py)."""

from __future__ import annotations

import sys
import threading

from rclpy.node import Node

from tiling_ros.spinning import run_node


class HangingTeardownNode(Node):
    def __init__(self) -> None:
        super().__init__("hanging_teardown_node")
        print("ready", flush=True)

    def destroy_node(self) -> None:
        threading.Event().wait()  # blocks for good, like the middleware's teardown did


if __name__ == "__main__":
    sys.exit(run_node(HangingTeardownNode))
