"""ROS stamps (builtin_interfaces Time or Duration: `sec` and `nanosec`) <-> seconds and nanoseconds."""

from __future__ import annotations

from typing import Any

from builtin_interfaces.msg import Time

NANOSECONDS_PER_SECOND = 10**9


def stamp_to_seconds(stamp: Any) -> float:
    """Seconds of a Time or Duration message (or any object with `sec` and `nanosec`)."""
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_to_nanoseconds(stamp: Any) -> int:
    """Nanoseconds of a Time or Duration message, exactly."""
    return int(stamp.sec) * NANOSECONDS_PER_SECOND + int(stamp.nanosec)


def stamp_from_nanoseconds(nanoseconds: int) -> Time:
    """The Time message `nanoseconds` after zero."""
    sec, nanosec = divmod(int(nanoseconds), NANOSECONDS_PER_SECOND)
    return Time(sec=sec, nanosec=nanosec)


def stamp_from_seconds(seconds: float) -> Time:
    """The Time message `seconds` after zero, to the nearest nanosecond."""
    return stamp_from_nanoseconds(round(seconds * 1e9))


def is_zero(stamp: Any) -> bool:
    """Whether a stamp is unset (0 s, 0 ns)."""
    return not (stamp.sec or stamp.nanosec)
