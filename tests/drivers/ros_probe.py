"""The tests' own ROS node (one per test session), spun in a background thread: it subscribes to
what the driver nodes publish and publishes what they consume."""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, Generic, TypeVar

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, ShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from rclpy.time import Time

T = TypeVar("T")


class Collector(Generic[T]):
    """Messages of one subscription, with their arrival time (time.monotonic())."""

    def __init__(self) -> None:
        self.items: list[tuple[float, T]] = []
        self._condition = threading.Condition()

    def add(self, message: T) -> None:
        with self._condition:
            self.items.append((time.monotonic(), message))
            self._condition.notify_all()

    def clear(self) -> None:
        with self._condition:
            self.items.clear()

    @property
    def messages(self) -> list[T]:
        with self._condition:
            return [m for _, m in self.items]

    def latest(self) -> T | None:
        with self._condition:
            return self.items[-1][1] if self.items else None

    def wait_for(self, predicate: Callable[[T], bool], timeout: float, what: str = "a matching message",
                 after: float = -1.0) -> T:
        """The first message (arrived after `after`) that satisfies `predicate`."""
        deadline = time.monotonic() + timeout
        with self._condition:
            while True:
                for stamp, message in self.items:
                    if stamp > after and predicate(message):
                        return message
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    last = self.items[-1][1] if self.items else None
                    raise AssertionError(f"no {what} within {timeout} s (last message: {last}; {probe_health()})")
                self._condition.wait(remaining)


def wait_for_future(future: Any, timeout: float, what: str) -> Any:
    """The future's result, once the probe's executor has completed it."""
    deadline = time.monotonic() + timeout
    while not future.done():
        if time.monotonic() > deadline:
            raise AssertionError(f"{what} did not complete within {timeout} s ({probe_health()})")
        time.sleep(0.02)
    return future.result()


class RosProbe:
    """rclpy Jazzy's executors are not safe against entities created or destroyed from another thread
    while they wait (ros2/rclpy#1385, #1589): the wait set can meet an action client being torn down
    and the executor's spin raises. The probe therefore keeps spinning past such an error, and the
    entities tests are done with are kept, not destroyed (`retire`). It spins in the session's domain
    to the end of the session; its DDS participant is never deleted (`ros_helpers.isolated_domains`)."""

    def __init__(self) -> None:
        if not rclpy.ok():
            rclpy.init()
        self.node = Node("drivers_test_probe")
        self.executor = MultiThreadedExecutor(num_threads=2)
        self.executor.add_node(self.node)
        self.spin_errors: list[str] = []
        self._retired: list[Any] = []
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while True:
            try:
                self.executor.spin_once(timeout_sec=0.1)
            except (ShutdownException, ExternalShutdownException):
                return
            except Exception as error:  # see the class docstring
                if not rclpy.ok():
                    return
                self.spin_errors.append(f"{type(error).__name__}: {error}")

    def retire(self, entity: Any) -> None:
        """Keep `entity` (a client, subscription …) to the end of the session: destroyed while the probe
        spins, it can break the spin."""
        self._retired.append(entity)

    def collect(self, message_type: Any, topic: str,
                qos: QoSProfile | int = qos_profile_sensor_data) -> Collector:
        collector: Collector = Collector()
        self.node.create_subscription(message_type, topic, collector.add, qos)
        return collector

    def publisher(self, message_type: Any, topic: str, qos: QoSProfile | int = 10,
                  wait_for_subscriber: float = 0.0) -> Any:
        """A publisher; with `wait_for_subscriber`, once a subscriber has been discovered (so that
        the first message is not lost to discovery)."""
        publisher = self.node.create_publisher(message_type, topic, qos)
        deadline = time.monotonic() + wait_for_subscriber
        while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        if wait_for_subscriber and publisher.get_subscription_count() == 0:
            raise AssertionError(f"nobody subscribes {topic} after {wait_for_subscriber} s")
        return publisher


class OverheadCamera:
    """Publishes the Create emulator's true pose as the overhead cameras would."""

    def __init__(self, pose_file: Path, topic: str) -> None:
        self.pose_file = pose_file
        self.publisher = shared_probe().publisher(PoseStamped, topic)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(0.2):
            try:
                x, y, yaw, seen = (float(v) for v in self.pose_file.read_text().split()[:4])
            except (OSError, ValueError):
                continue
            msg = PoseStamped()
            msg.header.frame_id = "map"
            now = shared_probe().node.get_clock().now().nanoseconds * 1e-9
            msg.header.stamp = Time(seconds=now - (time.monotonic() - seen)).to_msg()
            msg.pose.position.x, msg.pose.position.y = x, y
            msg.pose.orientation.z, msg.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
            self.publisher.publish(msg)

    def close(self) -> None:
        self._stop.set()


_probe: RosProbe | None = None


def probe_health() -> str:
    """Whether the probe still spins, and what interrupted it: said when a wait fails."""
    if _probe is None:
        return "no probe"
    alive = "spinning" if _probe._thread.is_alive() else "NOT spinning"
    return f"probe {alive}, spin errors: {_probe.spin_errors[-3:] or 'none'}"


def shared_probe() -> RosProbe:
    """The session's probe node (created on first use; it spins to the end of the session)."""
    global _probe
    if _probe is None:
        _probe = RosProbe()
    return _probe
