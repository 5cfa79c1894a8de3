"""Odometry of a differential-drive base from what the Create reports (no ROS).

Create 1 reports distance (mm) and angle (degrees) since its previous report; Create 2 is better
served by its wheel encoder counts (16 bits, wrapping), since its distance and angle packets are
known to be unreliable. Both feed the same integrator: a midpoint (second order) step per report.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from hardware_drivers.planar_pose import Pose2D, wrap_angle


@dataclass(frozen=True)
class WheelGeometry:
    wheel_base: float  # m, distance between the wheels' contact points
    wheel_diameter: float  # m (encoders only)
    ticks_per_revolution: float  # encoder counts per wheel turn (encoders only)

    @property
    def metres_per_tick(self) -> float:
        return math.pi * self.wheel_diameter / self.ticks_per_revolution


CREATE1_WHEELS = WheelGeometry(wheel_base=0.258, wheel_diameter=0.078, ticks_per_revolution=508.8)
CREATE2_WHEELS = WheelGeometry(wheel_base=0.235, wheel_diameter=0.072, ticks_per_revolution=508.8)


def encoder_delta(previous: int, current: int, modulus: int = 65536) -> int:
    """Signed change of a wrapping counter (assumes less than half a wrap between readings)."""
    return (current - previous + modulus // 2) % modulus - modulus // 2


def wheel_speeds(linear: float, angular: float, wheel_base: float,
                 max_wheel_speed: float) -> tuple[float, float]:
    """(right, left) wheel speeds (m/s) for a body twist, scaled down together so that neither
    exceeds `max_wheel_speed` (keeps the commanded curvature)."""
    right = linear + angular * wheel_base / 2.0
    left = linear - angular * wheel_base / 2.0
    largest = max(abs(right), abs(left))
    if largest > max_wheel_speed:
        scale = max_wheel_speed / largest
        right, left = right * scale, left * scale
    return right, left


class DifferentialOdometry:
    """Integrates (distance, heading change) steps into a pose and estimates the body twist."""

    def __init__(self, velocity_window: float = 0.1) -> None:
        self.pose = Pose2D()
        self.linear_velocity = 0.0  # m/s
        self.angular_velocity = 0.0  # rad/s
        self._window = velocity_window
        self._recent: deque[tuple[float, float, float]] = deque()  # (time, distance, dyaw)

    def reset(self) -> None:
        self.pose = Pose2D()
        self.linear_velocity = self.angular_velocity = 0.0
        self._recent.clear()

    def advance(self, distance: float, dyaw: float, stamp: float) -> Pose2D:
        heading = self.pose.yaw + dyaw / 2.0
        self.pose = Pose2D(
            self.pose.x + distance * math.cos(heading),
            self.pose.y + distance * math.sin(heading),
            wrap_angle(self.pose.yaw + dyaw),
        )
        self._recent.append((stamp, distance, dyaw))
        while len(self._recent) > 2 and stamp - self._recent[0][0] > self._window:
            self._recent.popleft()
        if len(self._recent) >= 2:
            span = stamp - self._recent[0][0]
            if span > 0:
                # the oldest step happened before the window's first stamp: leave it out
                self.linear_velocity = sum(d for _, d, _ in list(self._recent)[1:]) / span
                self.angular_velocity = sum(a for _, _, a in list(self._recent)[1:]) / span
        return self.pose


class EncoderOdometry:
    """Turns the Create 2's left/right encoder counts into (distance, dyaw) steps."""

    def __init__(self, wheels: WheelGeometry) -> None:
        self.wheels = wheels
        self._last: tuple[int, int] | None = None

    def reset(self) -> None:
        self._last = None

    def step(self, left_count: int, right_count: int) -> tuple[float, float]:
        if self._last is None:
            self._last = (left_count, right_count)
            return 0.0, 0.0
        d_left = encoder_delta(self._last[0], left_count) * self.wheels.metres_per_tick
        d_right = encoder_delta(self._last[1], right_count) * self.wheels.metres_per_tick
        self._last = (left_count, right_count)
        return (d_left + d_right) / 2.0, (d_right - d_left) / self.wheels.wheel_base
