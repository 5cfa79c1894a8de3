"""Kinematics of the CrustCrawler 5-DOF arm of the M3 robots (paper section 3.1), no ROS.

Joints: base yaw q1 (about the arm base's z axis), shoulder q2, elbow q3 and wrist pitch q4 (all
about the horizontal axis across the arm, positive raising the link), wrist roll q5 (about the
tool axis). At q = 0 the arm is stretched out horizontally along the arm base's +x.

Frame of the arm base: z up, x forward. The shoulder axis is `shoulder_height` above the base, the
upper arm (`upper_arm`) reaches the elbow, the forearm (`forearm`) the wrist pitch axis, and the
tool point (between the fingertips) is `tool_length` further along the tool axis.

    planar reach:  shoulder (0, h)
                   elbow  = shoulder + l2 (cos q2, sin q2)
                   wrist  = elbow    + l3 (cos(q2+q3), sin(q2+q3))
                   tool   = wrist    + l4 (cos p, sin p),   p = q2 + q3 + q4 (tool pitch)
    then the plane turns by q1 about z.

The fingers close along the tool's y axis. For a tool pointing straight down (p = -pi/2), the
closing axis makes the angle q1 - q5 + pi/2 with the base's x axis: a *grasp yaw*
psi = q1 - q5 means the fingers close across the direction psi + pi/2, i.e. they grip a tile whose
yaw is psi across its y extent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hardware_drivers.planar_pose import wrap_angle

ARM_JOINTS = ("base_yaw", "shoulder", "elbow", "wrist_pitch", "wrist_roll")
DOWN = -math.pi / 2.0


class UnreachableError(ValueError):
    """A tool pose the arm cannot reach (out of reach or outside the joint limits)."""


@dataclass(frozen=True)
class ArmGeometry:
    shoulder_height: float = 0.065  # m, shoulder axis above the arm base
    upper_arm: float = 0.152  # m, shoulder to elbow
    forearm: float = 0.132  # m, elbow to wrist pitch axis
    tool_length: float = 0.105  # m, wrist pitch axis to the point between the fingertips
    lower: tuple[float, ...] = (-2.6, -1.6, -2.6, -2.0, -2.6)  # rad, joint limits q1..q5
    upper: tuple[float, ...] = (2.6, 2.0, 2.6, 2.0, 2.6)

    def validate(self) -> None:
        for name in ("shoulder_height", "upper_arm", "forearm", "tool_length"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"arm geometry: {name} must be a positive length, got {value}")
        if len(self.lower) != 5 or len(self.upper) != 5:
            raise ValueError("arm geometry: 5 lower and 5 upper joint limits are needed")
        if any(lo >= hi for lo, hi in zip(self.lower, self.upper, strict=True)):
            raise ValueError("arm geometry: every lower joint limit must be below its upper limit")


@dataclass(frozen=True)
class ToolPose:
    """Tool point position (m, arm base frame), tool pitch (rad, 0 horizontal, -pi/2 down) and
    wrist roll (rad); for a vertical tool, `grasp_yaw` (see the module docstring)."""

    x: float
    y: float
    z: float
    pitch: float
    roll: float

    def grasp_yaw(self) -> float:
        return wrap_angle(math.atan2(self.y, self.x) - self.roll)


def forward(geometry: ArmGeometry, q: Sequence[float]) -> ToolPose:
    q1, q2, q3, q4, q5 = (float(v) for v in q)
    pitch = q2 + q3 + q4
    reach = geometry.upper_arm * math.cos(q2) + geometry.forearm * math.cos(q2 + q3) \
        + geometry.tool_length * math.cos(pitch)
    height = geometry.shoulder_height + geometry.upper_arm * math.sin(q2) \
        + geometry.forearm * math.sin(q2 + q3) + geometry.tool_length * math.sin(pitch)
    return ToolPose(reach * math.cos(q1), reach * math.sin(q1), height, wrap_angle(pitch), wrap_angle(q5))


def tool_rotation(q: Sequence[float]) -> NDArray[np.float64]:
    """Rotation of the tool frame (x along the tool, y the fingers' closing axis) in the arm base."""
    q1, q2, q3, q4, q5 = (float(v) for v in q)
    pitch = q2 + q3 + q4

    def rz(a: float) -> NDArray[np.float64]:
        return np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])

    def ry(a: float) -> NDArray[np.float64]:
        return np.array([[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]])

    def rx(a: float) -> NDArray[np.float64]:
        return np.array([[1, 0, 0], [0, math.cos(a), -math.sin(a)], [0, math.sin(a), math.cos(a)]])

    return rz(q1) @ ry(-pitch) @ rx(q5)


def _within(geometry: ArmGeometry, q: Sequence[float]) -> str | None:
    for name, value, lo, hi in zip(ARM_JOINTS, q, geometry.lower, geometry.upper, strict=True):
        if not lo - 1e-9 <= value <= hi + 1e-9:
            return f"{name} would need {value:.2f} rad, outside [{lo:.2f}, {hi:.2f}]"
    return None


def inverse(geometry: ArmGeometry, pose: ToolPose) -> tuple[float, float, float, float, float]:
    """Joint angles reaching `pose` (elbow up preferred); UnreachableError with the reason otherwise."""
    r = math.hypot(pose.x, pose.y)
    if r < 1e-6:
        raise UnreachableError("a tool point on the base's axis has no defined base yaw")
    q1 = math.atan2(pose.y, pose.x)
    # the wrist pitch axis, in the arm's vertical plane, relative to the shoulder
    wr = r - geometry.tool_length * math.cos(pose.pitch)
    wz = pose.z - geometry.shoulder_height - geometry.tool_length * math.sin(pose.pitch)
    l2, l3 = geometry.upper_arm, geometry.forearm
    distance = math.hypot(wr, wz)
    cos_q3 = (distance**2 - l2**2 - l3**2) / (2.0 * l2 * l3)
    if cos_q3 > 1.0 + 1e-9 or cos_q3 < -1.0 - 1e-9:
        raise UnreachableError(
            f"wrist at {distance * 1000:.0f} mm from the shoulder is outside the arm's reach "
            f"[{abs(l2 - l3) * 1000:.0f}, {(l2 + l3) * 1000:.0f}] mm"
        )
    cos_q3 = max(-1.0, min(1.0, cos_q3))
    problems = []
    for sign in (-1.0, 1.0):  # elbow up (q3 < 0 bends the forearm down from a raised upper arm) first
        q3 = sign * math.acos(cos_q3)
        q2 = math.atan2(wz, wr) - math.atan2(l3 * math.sin(q3), l2 + l3 * math.cos(q3))
        q4 = pose.pitch - q2 - q3
        q = (q1, wrap_angle(q2), q3, wrap_angle(q4), wrap_angle(pose.roll))
        problem = _within(geometry, q)
        if problem is None:
            return q
        problems.append(problem)
    raise UnreachableError("; ".join(dict.fromkeys(problems)))


def top_down_grasp(geometry: ArmGeometry, x: float, y: float, z: float, grasp_yaw: float,
                   allow_flip: bool = True) -> tuple[float, ...]:
    """Joints putting the tool point at (x, y, z) pointing down, fingers closing across `grasp_yaw`.

    A parallel gripper grips the same way turned by pi: with `allow_flip` the roll closest to zero
    (of the two) that respects the wrist roll limits is chosen; without it, the grasp yaw is exact
    (placing a tile whose orientation in the fingers is known).
    """
    q1 = math.atan2(y, x)
    turns = (0, 1) if allow_flip else (0,)
    options = sorted((wrap_angle(q1 - grasp_yaw + k * math.pi) for k in turns), key=abs)
    problems = []
    for roll in options:
        try:
            return inverse(geometry, ToolPose(x, y, z, DOWN, roll))
        except UnreachableError as error:
            problems.append(str(error))
    raise UnreachableError("; ".join(dict.fromkeys(problems)))
