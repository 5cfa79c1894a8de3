"""A node process whose interpreter exit would never end (an atexit handler that blocks for good,
as freeing the middleware's leftovers at exit now and then did): stopped at Ctrl-C, the process
must still end (tests/test_executor_shutdown.py). Run as a script; it imports itself as the node
module, as the installed executables do."""

from __future__ import annotations

import atexit
import sys
import threading

from rclpy.node import Node

from tiling_assembly.interrupts import run_executable
from tiling_ros.spinning import run_node


class HangingExitNode(Node):
    def __init__(self) -> None:
        super().__init__("hanging_exit_node")
        atexit.register(threading.Event().wait)
        print("ready", flush=True)


def main() -> int:
    return run_node(HangingExitNode, on_shutdown=lambda node: print("stopped", flush=True))


if __name__ == "__main__":
    sys.exit(run_executable("hanging_exit_node"))
