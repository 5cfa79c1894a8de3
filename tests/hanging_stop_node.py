"""A node whose stop never returns (an `on_shutdown` hook blocked for good): the process must still end
before launch's SIGKILL, with one line (tests/test_executor_shutdown.py)."""

from __future__ import annotations

import sys
import threading

from rclpy.node import Node

from tiling_ros.spinning import run_node

STOP_PATIENCE = 1.0  # s; short, so that the test is quick


class HangingStopNode(Node):
    def __init__(self) -> None:
        super().__init__("hanging_stop_node")
        print("ready", flush=True)


def block_for_good(node: HangingStopNode) -> None:
    threading.Event().wait()


if __name__ == "__main__":
    sys.exit(run_node(HangingStopNode, on_shutdown=block_for_good, stop_patience=STOP_PATIENCE))
