"""Driving a differential base to a floor pose with odometry and the overhead cameras, no ROS.

Paper section 3.1: the robots were localized by overhead cameras (errors up to ~5 cm and ~10
degrees); between camera fixes, the base's odometry is smooth and precise over short distances.
:class:`PoseFusion` keeps the map pose as ``correction ∘ odometry``: each overhead fix pulls the
correction (map <- odom) toward agreement, by a weight that trades the cameras' noise for the
odometry's drift. :class:`GoToPose` is a rotate-drive-rotate controller producing body twists.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from hardware_drivers.planar_pose import Pose2D, wrap_angle


class PoseFusion:
    """Map pose of the base from odometry corrected by overhead fixes."""

    def __init__(self, fix_weight: float = 0.5) -> None:
        if not 0.0 < fix_weight <= 1.0:
            raise ValueError(f"fix_weight must be in (0, 1], got {fix_weight}")
        self.fix_weight = fix_weight
        self.correction: Pose2D | None = None  # map <- odom
        self.odometry: Pose2D | None = None
        self.fixes = 0

    def update_odometry(self, odom_pose: Pose2D) -> None:
        self.odometry = odom_pose

    def update_fix(self, map_pose: Pose2D, odom_pose: Pose2D | None = None) -> None:
        """An overhead fix of the base in the map, with the odometry pose of the same instant
        (default: the latest)."""
        odom = odom_pose or self.odometry
        if odom is None:
            return
        measured = map_pose.compose(odom.inverse())
        if self.correction is None:
            self.correction = measured
        else:
            w = self.fix_weight
            c = self.correction
            self.correction = Pose2D(
                c.x + w * (measured.x - c.x),
                c.y + w * (measured.y - c.y),
                wrap_angle(c.yaw + w * wrap_angle(measured.yaw - c.yaw)),
            )
        self.fixes += 1

    @property
    def ready(self) -> bool:
        return self.correction is not None and self.odometry is not None

    def map_pose(self) -> Pose2D:
        if self.correction is None or self.odometry is None:
            raise RuntimeError("no overhead fix or no odometry yet")
        return self.correction.compose(self.odometry)


def approach_pose(target_x: float, target_y: float, from_x: float, from_y: float, standoff: float) -> Pose2D:
    """The pose `standoff` metres from the target on the line toward (from_x, from_y), facing the
    target."""
    dx, dy = from_x - target_x, from_y - target_y
    distance = math.hypot(dx, dy)
    if distance < 1e-6:
        dx, dy, distance = -1.0, 0.0, 1.0
    x = target_x + dx / distance * standoff
    y = target_y + dy / distance * standoff
    return Pose2D(x, y, math.atan2(target_y - y, target_x - x))


@dataclass(frozen=True)
class GoToPoseParams:
    max_linear: float = 0.2  # m/s
    max_angular: float = 1.0  # rad/s
    linear_gain: float = 1.5  # 1/s
    angular_gain: float = 3.0  # 1/s
    position_tolerance: float = 0.01  # m
    yaw_tolerance: float = 0.02  # rad
    turn_in_place_above: float = 0.35  # rad of heading error
    reverse_within: float = 0.3  # m: a goal this close behind the robot is reached backwards
    near: float = 0.04  # m: closer than this, only move along the heading (no turning toward the goal)
    min_linear: float = 0.02  # m/s, to overcome the last centimetres
    min_angular: float = 0.1  # rad/s


class GoToPose:
    """Rotate toward the goal, drive to it correcting the heading, rotate to the goal's yaw.

    Within ``near`` of the goal it only moves along its heading: turning toward a goal a few
    millimetres to the side would make the base circle around it.
    """

    def __init__(self, params: GoToPoseParams | None = None) -> None:
        self.params = params or GoToPoseParams()
        self._aligning = False

    def reset(self) -> None:
        self._aligning = False

    def command(self, pose: Pose2D, goal: Pose2D) -> tuple[float, float, bool]:
        """(linear m/s, angular rad/s, done) for the current pose."""
        p = self.params
        dx, dy = goal.x - pose.x, goal.y - pose.y
        distance = math.hypot(dx, dy)
        if self._aligning and distance > 1.5 * p.near:
            self._aligning = False  # pushed away: approach again
        if not self._aligning:
            along = dx * math.cos(pose.yaw) + dy * math.sin(pose.yaw)
            arrived = distance <= p.position_tolerance
            if arrived or (distance <= p.near and abs(along) <= p.position_tolerance):
                self._aligning = True
            elif distance <= p.near:
                speed = min(p.max_linear, max(p.min_linear, p.linear_gain * abs(along)))
                return math.copysign(speed, along), 0.0, False
            else:
                return self._approach(dx, dy, distance, pose.yaw)
        yaw_error = wrap_angle(goal.yaw - pose.yaw)
        if abs(yaw_error) > p.yaw_tolerance:
            return 0.0, self._turn(yaw_error), False
        return 0.0, 0.0, True

    def _approach(self, dx: float, dy: float, distance: float, yaw: float) -> tuple[float, float, bool]:
        p = self.params
        heading_error = wrap_angle(math.atan2(dy, dx) - yaw)
        backwards = distance < p.reverse_within and abs(heading_error) > math.pi / 2.0
        if backwards:
            heading_error = wrap_angle(heading_error + math.pi)
        angular = self._turn(heading_error)
        if abs(heading_error) > p.turn_in_place_above:
            return 0.0, angular, False
        linear = min(p.max_linear, max(p.min_linear, p.linear_gain * distance)) * math.cos(heading_error)
        return (-linear if backwards else linear), angular, False

    def _turn(self, error: float) -> float:
        p = self.params
        rate = min(p.max_angular, max(p.min_angular, p.angular_gain * abs(error)))
        return math.copysign(rate, error) if abs(error) > 1e-4 else 0.0
