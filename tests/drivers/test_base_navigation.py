"""Driving the base: pose algebra, odometry corrected by overhead fixes, the go-to-pose controller
converging on a simulated differential drive."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hardware_drivers.base_navigation import GoToPose, GoToPoseParams, PoseFusion, approach_pose
from hardware_drivers.differential_odometry import (
    CREATE2_WHEELS,
    DifferentialOdometry,
    EncoderOdometry,
    encoder_delta,
    wheel_speeds,
)
from hardware_drivers.planar_pose import Pose2D, wrap_angle


def test_pose_algebra() -> None:
    a, b = Pose2D(1.0, 2.0, 0.5), Pose2D(-0.3, 0.4, -1.2)
    ab = a.compose(b)
    back = a.inverse().compose(ab)
    assert (back.x, back.y, back.yaw) == pytest.approx((b.x, b.y, b.yaw))
    point = a.transform_points(np.array([[b.x, b.y]]))[0]
    assert point == pytest.approx([ab.x, ab.y])
    assert wrap_angle(3 * math.pi) == pytest.approx(-math.pi)


def test_fixes_correct_the_odometry() -> None:
    fusion = PoseFusion(fix_weight=0.5)
    fusion.update_odometry(Pose2D(0.0, 0.0, 0.0))
    assert not fusion.ready
    fusion.update_fix(Pose2D(1.0, 1.0, math.pi / 2))  # the first fix is taken whole
    fusion.update_odometry(Pose2D(0.5, 0.0, 0.0))  # half a metre forward in odom
    pose = fusion.map_pose()
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((1.0, 1.5, math.pi / 2))
    fusion.update_fix(Pose2D(1.1, 1.5, math.pi / 2))  # the camera sees it 10 cm further right
    assert fusion.map_pose().x == pytest.approx(1.05)  # pulled half way
    # a fix taken when odometry was elsewhere is applied against that odometry pose
    fusion.update_fix(Pose2D(1.05, 1.5, math.pi / 2), odom_pose=Pose2D(0.5, 0.0, 0.0))
    assert fusion.map_pose().x == pytest.approx(1.05)


def test_approach_pose_faces_the_target_from_the_robot_side() -> None:
    stop = approach_pose(1.0, 0.0, 0.0, 0.0, 0.3)
    assert (stop.x, stop.y, stop.yaw) == pytest.approx((0.7, 0.0, 0.0))


@pytest.mark.parametrize("goal", [Pose2D(1.0, 0.5, 2.0), Pose2D(-0.5, -0.8, -0.3), Pose2D(-0.1, 0.0, 0.0),
                                  Pose2D(0.02, 0.01, 1.0)])
def test_controller_brings_a_differential_drive_to_the_goal(goal: Pose2D) -> None:
    params = GoToPoseParams()
    controller = GoToPose(params)
    pose = Pose2D(0.0, 0.0, 0.0)
    dt = 0.05
    reversed_once = False
    for _ in range(2000):
        linear, angular, done = controller.command(pose, goal)
        if done:
            break
        assert abs(linear) <= params.max_linear + 1e-9 and abs(angular) <= params.max_angular + 1e-9
        reversed_once |= linear < 0
        pose = Pose2D(pose.x + linear * dt * math.cos(pose.yaw), pose.y + linear * dt * math.sin(pose.yaw),
                      wrap_angle(pose.yaw + angular * dt))
    else:
        pytest.fail(f"did not reach {goal}; at {pose}")
    assert pose.distance_to(goal) <= 1.5 * params.position_tolerance
    assert abs(wrap_angle(pose.yaw - goal.yaw)) <= params.yaw_tolerance
    assert reversed_once == (goal.x == -0.1)  # a goal just behind is reached backwards


def test_wheel_speeds_keep_the_curvature_when_clamped() -> None:
    right, left = wheel_speeds(0.4, 3.0, 0.258, 0.5)
    assert max(abs(right), abs(left)) == pytest.approx(0.5)
    unclamped = wheel_speeds(0.4, 3.0, 0.258, 10.0)
    assert right / left == pytest.approx(unclamped[0] / unclamped[1])


def test_odometry_integration_and_encoder_wrap() -> None:
    assert encoder_delta(65530, 4) == 10 and encoder_delta(4, 65530) == -10
    encoders = EncoderOdometry(CREATE2_WHEELS)
    assert encoders.step(65500, 65500) == (0.0, 0.0)
    distance, dyaw = encoders.step(100, 100)  # 136 counts forward on both wheels, across the wrap
    assert distance == pytest.approx(136 * CREATE2_WHEELS.metres_per_tick) and dyaw == 0.0
    odometry = DifferentialOdometry()
    for k in range(100):  # a quarter circle of radius 1 m in 100 steps
        odometry.advance(math.pi / 2 / 100, math.pi / 2 / 100, k * 0.01)
    pose = odometry.pose
    assert (pose.x, pose.y, pose.yaw) == pytest.approx((1.0, 1.0, math.pi / 2), abs=1e-4)
    assert odometry.linear_velocity == pytest.approx(math.pi / 2, rel=1e-6)
