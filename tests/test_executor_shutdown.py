"""Stopping a multi-threaded executor waits for the callbacks still running on its threads."""

from __future__ import annotations

import threading
import time

import pytest
import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from std_msgs.msg import Empty

from tiling_assembly.spinning import stop_executor

pytestmark = pytest.mark.ros


def test_a_running_callback_finishes_before_the_node_is_destroyed() -> None:
    context = rclpy.Context()
    rclpy.init(context=context)
    node = rclpy.create_node("slow_callback", context=context)
    publisher = node.create_publisher(Empty, "slow_callback_done", 1)
    started, finished = threading.Event(), threading.Event()

    def slow() -> None:
        if started.is_set():
            return
        started.set()
        time.sleep(0.5)
        publisher.publish(Empty())  # fails if the node was destroyed meanwhile
        finished.set()

    node.create_timer(0.01, slow, callback_group=ReentrantCallbackGroup())
    executor = MultiThreadedExecutor(num_threads=2, context=context)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin)
    spinner.start()
    try:
        assert started.wait(10.0)
        stop_executor(executor)
        assert finished.is_set()  # rclpy's own shutdown returns while the callback still sleeps
        spinner.join(5.0)
        assert not spinner.is_alive()
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=context)
