"""Poses on the floor plane (x, y, yaw), the frame algebra the base, laser and mission share.

REP 103: metres and radians, yaw counter-clockwise about z. ``a.compose(b)`` is the pose b given in
frame a, expressed in a's parent frame (a ∘ b).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


def wrap_angle(angle: float) -> float:
    """The same angle in [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True)
class Pose2D:
    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0

    def compose(self, other: Pose2D) -> Pose2D:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2D(
            self.x + c * other.x - s * other.y,
            self.y + s * other.x + c * other.y,
            wrap_angle(self.yaw + other.yaw),
        )

    def inverse(self) -> Pose2D:
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return Pose2D(-c * self.x - s * self.y, s * self.x - c * self.y, wrap_angle(-self.yaw))

    def transform_points(self, points: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N, 2) points given in this pose's frame, expressed in its parent frame."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        rotation = np.array([[c, -s], [s, c]])
        return np.asarray(points, dtype=float) @ rotation.T + np.array([self.x, self.y])

    def distance_to(self, other: Pose2D) -> float:
        return math.hypot(other.x - self.x, other.y - self.y)

    def __str__(self) -> str:
        return f"({self.x:.3f} m, {self.y:.3f} m, {math.degrees(self.yaw):.1f} deg)"
