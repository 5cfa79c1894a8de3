"""Spinning a test's executor until something happens (or a wall-clock deadline passes)."""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.executors import Executor


def spin_until(executor: Executor, predicate: Callable[[], bool], timeout: float) -> bool:
    """Spin `executor` until `predicate()` holds (True) or `timeout` s of wall time pass (False)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
        if predicate():
            return True
    return False
