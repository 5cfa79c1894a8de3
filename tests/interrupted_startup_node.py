"""A node process signalled during its start-up (tests/test_executor_shutdown.py).

    interrupted_startup_node.py SIGNAL import        the signal lands while the node's module is
                                                     imported, and comes out as ImportError, as a
                                                     C extension's initialisation (Open3D's) makes it
    interrupted_startup_node.py SIGNAL construction  the signal lands while the node is being built
    interrupted_startup_node.py SIGNAL executor      the signal lands while its executor is being built
"""

from __future__ import annotations

import os
import signal
import sys
import time

from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from tiling_assembly.interrupts import run_executable
from tiling_ros.spinning import run_node


def signal_myself() -> None:
    os.kill(os.getpid(), getattr(signal, sys.argv[1]))


class SlowStartingNode(Node):
    """Built in a second (as one that imports Open3D): a signal meanwhile must wait for the node."""

    def __init__(self) -> None:
        super().__init__("interrupted_startup_node")
        signal_myself()
        time.sleep(1.0)
        print("built", flush=True)


class QuickNode(Node):
    def __init__(self) -> None:
        super().__init__("interrupted_startup_node")
        print("built", flush=True)


class SlowStartingExecutor(SingleThreadedExecutor):
    """An executor whose construction the signal interrupts, as a signal landing in rclpy's
    Executor.__init__ does: cut short, its __del__ failed ("Exception ignored in ... __del__")."""

    def __init__(self) -> None:
        signal_myself()
        time.sleep(0.5)
        super().__init__()


def main() -> int:
    if sys.argv[2] == "executor":
        return run_node(QuickNode, executor=SlowStartingExecutor, on_shutdown=lambda node: print("stopped", flush=True))
    return run_node(SlowStartingNode, on_shutdown=lambda node: print("stopped", flush=True))


if __name__ == "__main__":
    if sys.argv[2] == "import":
        sys.exit(run_executable("interrupted_import"))  # tests/interrupted_import.py
    sys.exit(main())
