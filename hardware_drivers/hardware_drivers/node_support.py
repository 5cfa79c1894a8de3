"""What the driver nodes share on the ROS side: declared and validated parameters, diagnostics
from a driver's health, driver events as log lines, and a clean main loop.

Kept apart from the drivers so that they stay ROS-free; every node uses these the same way.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration
from rclpy.executors import Executor, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile, ReliabilityPolicy

from hardware_drivers.device_health import HealthReport, Level
from tiling_assembly import spinning

NodeT = TypeVar("NodeT", bound=Node)

DIAGNOSTICS_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
# REP 2003: sensor drivers publish reliable, so best-effort and reliable subscribers both connect
SENSOR_PUBLISHER_QOS = QoSProfile(depth=5, reliability=ReliabilityPolicy.RELIABLE)


class ParameterError(ValueError):
    """A parameter value the node cannot start with (one line)."""


def declare(node: Node, name: str, default: Any, description: str) -> Any:
    """Declare a parameter with a description and return its value."""
    node.declare_parameter(name, default, ParameterDescriptor(description=description))
    return node.get_parameter(name).value


def require(condition: bool, message: str) -> None:
    if not condition:
        raise ParameterError(message)


def positive(node: Node, name: str, default: float, description: str) -> float:
    value = float(declare(node, name, default, description))
    require(value > 0, f"parameter {name} must be positive, got {value}")
    return value


def floats(node: Node, name: str, default: Sequence[float], description: str,
           length: int | None = None) -> list[float]:
    value = [float(v) for v in declare(node, name, list(map(float, default)), description)]
    if length is not None:
        require(len(value) == length, f"parameter {name} needs {length} numbers, got {len(value)}")
    return value


def log_event(node: Node, level: Level, message: str) -> None:
    """A driver event as one log line."""
    logger = node.get_logger()
    if level == Level.OK:
        logger.info(message)
    elif level == Level.WARN:
        logger.warning(message)
    else:
        logger.error(message)


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
        self.publisher = node.create_publisher(DiagnosticArray, "/diagnostics", DIAGNOSTICS_QOS)
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
    """A driver node's whole process (`tiling_assembly.spinning.run_node`): a ParameterError is one
    line on stderr and exit code 2. Returns the exit code."""
    return spinning.run_node(make_node, (ParameterError,), args=sys.argv, executor=executor,
                             on_stop=on_stop, on_shutdown=on_shutdown)
