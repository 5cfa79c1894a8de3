"""What the driver nodes share on the ROS side: checks of their settings (declared through
`tiling_ros.parameters`), diagnostics from a driver's health, driver events as log lines, and a
clean main loop.

Kept apart from the drivers so that they stay ROS-free; every node uses these the same way.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.duration import Duration
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher

from hardware_drivers.device_health import HealthReport, Level
from tiling_ros import spinning
from tiling_ros.parameters import declare_parameter
from tiling_ros.qos import DIAGNOSTICS

NodeT = TypeVar("NodeT", bound=Node)
DriverT = TypeVar("DriverT")
EventSink = Callable[[Level, str], None]  # a driver's on_event


class ParameterError(ValueError):
    """A parameter value the node cannot start with (one line)."""


def require(condition: bool, message: str) -> None:
    if not condition:
        raise ParameterError(message)


def require_positive(settings: Any, *names: str) -> None:
    """Each named setting must be a positive number."""
    for name in names:
        value = float(getattr(settings, name))
        require(value > 0, f"parameter {name} must be positive, got {value}")


def numbers(settings: Any, name: str, length: int | None = None) -> list[float]:
    """A list setting as floats, of `length` numbers when given."""
    return checked_numbers(name, getattr(settings, name), length)


def checked_numbers(name: str, values: Sequence[float], length: int | None = None) -> list[float]:
    value = [float(v) for v in values]
    if length is not None:
        require(len(value) == length, f"parameter {name} needs {length} numbers, got {len(value)}")
    return value


def declare_numbers(node: Node, name: str, default: Sequence[float], description: str,
                    length: int | None = None) -> list[float]:
    """One list-of-floats parameter whose name depends on other parameters (a named arm pose)."""
    return checked_numbers(name, declare_parameter(node, name, [float(v) for v in default], description), length)


def log_event(node: Node, level: Level, message: str) -> None:
    """A driver event as one log line."""
    logger = node.get_logger()
    if level == Level.OK:
        logger.info(message)
    elif level == Level.WARN:
        logger.warning(message)
    else:
        logger.error(message)


def build_driver(node: Node, build: Callable[[EventSink], DriverT]) -> DriverT:
    """`build(on_event)` with the driver's events logged by `node`; a ValueError (a setting the
    driver refuses) becomes a ParameterError, so that the node stops with one line."""
    try:
        return build(lambda level, text: log_event(node, level, text))
    except ValueError as error:
        raise ParameterError(str(error)) from None


def monotonic_offset(node: Node) -> float:
    """s to add to a driver's time.monotonic() stamp to put it on `node`'s clock."""
    return node.get_clock().now().nanoseconds * 1e-9 - time.monotonic()


def device_diagnostics(node: Node, device: str, hardware_id: str,
                       health: Callable[[], HealthReport]) -> DiagnosticsReporter:
    """/diagnostics of `device` (on `hardware_id`, its port), named after the node."""
    return DiagnosticsReporter(node, f"{node.get_fully_qualified_name()}: {device}", hardware_id, health)


def diagnostic_status(report: HealthReport, name: str, hardware_id: str) -> DiagnosticStatus:
    return DiagnosticStatus(
        level=bytes([int(report.level)]),
        name=name,
        message=report.message,
        hardware_id=hardware_id,
        values=[KeyValue(key=k, value=v) for k, v in report.values.items()],
    )


class DiagnosticsReporter:
    """Publishes a device's health on /diagnostics once a second and at every change of level or
    message."""

    def __init__(self, node: Node, name: str, hardware_id: str, health: Callable[[], HealthReport],
                 period: float = 1.0) -> None:
        self.node = node
        self.name = name
        self.hardware_id = hardware_id
        self.health = health
        self.publisher = node.create_publisher(DiagnosticArray, "/diagnostics", DIAGNOSTICS)
        self._last: tuple[int, str] | None = None
        self._since = 0.0
        self._period = period
        node.create_timer(0.1, self._tick)

    def _tick(self) -> None:
        report = self.health()
        key = (int(report.level), report.message)
        self._since += 0.1
        if key != self._last or self._since >= self._period - 1e-6:
            self.publish(report)

    def publish(self, report: HealthReport | None = None) -> None:
        report = report or self.health()
        self._last = (int(report.level), report.message)
        self._since = 0.0
        array = DiagnosticArray()
        array.header.stamp = self.node.get_clock().now().to_msg()
        array.status = [diagnostic_status(report, self.name, self.hardware_id)]
        self.publisher.publish(array)


def publish_last(publisher: Publisher, message: Any, timeout: float = 1.0) -> None:
    """Publish a node's last word (the zero Twist that stops the wheels) and wait up to `timeout`
    s until every subscriber has acknowledged it: a publisher destroyed right after publishing can
    take an unacknowledged message with it, and the wheels would roll on until the base's watchdog."""
    publisher.publish(message)
    publisher.wait_for_all_acked(Duration(seconds=timeout))


def run_node(make_node: Callable[[], NodeT], executor: Callable[[], Executor] = SingleThreadedExecutor,
             on_stop: Callable[[NodeT], None] | None = None,
             on_shutdown: Callable[[NodeT], None] | None = None) -> int:
    """A driver node's whole process (`tiling_ros.spinning.run_node`): a ParameterError is one
    line on stderr and exit code 2. Returns the exit code."""
    return spinning.run_node(make_node, (ParameterError,), args=sys.argv, executor=executor,
                             on_stop=on_stop, on_shutdown=on_shutdown)
