"""Health of one serial device, as the drivers report it (no ROS).

Each driver keeps one :class:`DeviceHealth`: a level (the values of
``diagnostic_msgs/DiagnosticStatus``), a one-line message and counters (frames, corrupt frames,
reconnects...). Nodes publish snapshots on ``/diagnostics`` and log the driver's events, so a user
sees one clear line per event and the counters in ``ros2 topic echo /diagnostics``.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import IntEnum


class Level(IntEnum):
    """diagnostic_msgs/DiagnosticStatus levels."""

    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3


@dataclass(frozen=True)
class HealthReport:
    level: Level
    message: str
    values: dict[str, str] = field(default_factory=dict)


EventSink = Callable[[Level, str], None]


class DeviceHealth:
    """Thread-safe level, message and counters of one device, with an event callback.

    ``event`` reports something that happened (one log line); ``set_state`` sets the standing
    status shown in diagnostics; counters accumulate.
    """

    def __init__(self, on_event: EventSink | None = None) -> None:
        self._lock = threading.Lock()
        self._level = Level.STALE
        self._message = "not connected yet"
        self._counters: dict[str, int] = {}
        self._values: dict[str, str] = {}
        self._on_event = on_event

    def set_state(self, level: Level, message: str) -> None:
        with self._lock:
            self._level, self._message = level, message

    def event(self, level: Level, message: str, *, set_state: bool = False) -> None:
        if set_state:
            self.set_state(level, message)
        if self._on_event is not None:
            self._on_event(level, message)

    def count(self, name: str, amount: int = 1) -> None:
        with self._lock:
            self._counters[name] = self._counters.get(name, 0) + amount

    def set_counter(self, name: str, value: int) -> None:
        with self._lock:
            self._counters[name] = value

    def counter(self, name: str) -> int:
        with self._lock:
            return self._counters.get(name, 0)

    def set_value(self, name: str, value: object) -> None:
        with self._lock:
            self._values[name] = str(value)

    @property
    def level(self) -> Level:
        with self._lock:
            return self._level

    def snapshot(self) -> HealthReport:
        with self._lock:
            values = {**self._values, **{k: str(v) for k, v in sorted(self._counters.items())}}
            return HealthReport(self._level, self._message, values)
