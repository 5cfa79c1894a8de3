"""A node whose destruction blocks inside a C call that holds the interpreter, as rclpy's publisher
destroy did in vi_node: the process must still end (tests/test_executor_shutdown.py)."""

from __future__ import annotations

import ctypes
import sys

from rclpy.node import Node

from tiling_ros.spinning import run_node


class GilHoldingTeardownNode(Node):
    def __init__(self) -> None:
        super().__init__("gil_holding_teardown_node")
        print("ready", flush=True)

    def destroy_node(self) -> None:
        ctypes.PyDLL(None).sleep(60)  # libc's sleep through PyDLL: the interpreter stays held


if __name__ == "__main__":
    sys.exit(run_node(GilHoldingTeardownNode))
