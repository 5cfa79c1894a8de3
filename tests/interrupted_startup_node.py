"""A node whose start-up is interrupted inside what looks like a C extension's initialisation: the
KeyboardInterrupt of Ctrl-C / SIGTERM comes out as another exception, as Open3D's import does
(tests/test_executor_shutdown.py)."""

from __future__ import annotations

import os
import signal
import sys
import time

from rclpy.node import Node

from tiling_assembly.spinning import run_node


class InterruptedStartupNode(Node):
    def __init__(self) -> None:
        super().__init__("interrupted_startup_node")
        try:
            os.kill(os.getpid(), getattr(signal, sys.argv[1]))
            time.sleep(5.0)
        except KeyboardInterrupt as interrupt:
            raise ImportError("initialization failed") from interrupt


if __name__ == "__main__":
    sys.exit(run_node(InterruptedStartupNode, (ValueError,)))
