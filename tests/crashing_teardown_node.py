"""A node whose destruction crashes (SIGSEGV), as Fast DDS did once in rclpy's destroy_node under
auction_node: the process must still end with one line and exit code 0 (tests/test_executor_shutdown.py)."""

from __future__ import annotations

import ctypes
import sys

from rclpy.node import Node

from tiling_ros.spinning import run_node


class CrashingTeardownNode(Node):
    def __init__(self) -> None:
        super().__init__("crashing_teardown_node")
        print("ready", flush=True)

    def destroy_node(self) -> None:
        ctypes.string_at(0)  # reads address 0: SIGSEGV inside a C call


if __name__ == "__main__":
    sys.exit(run_node(CrashingTeardownNode))
