"""CrustCrawler arm kinematics: forward(inverse(p)) == p, top-down grasps, unreachable poses."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hardware_drivers.arm_kinematics import (
    DOWN,
    ArmGeometry,
    ToolPose,
    UnreachableError,
    forward,
    inverse,
    tool_rotation,
    top_down_grasp,
)
from hardware_drivers.planar_pose import wrap_angle

GEOMETRY = ArmGeometry()


def assert_same_pose(a: ToolPose, b: ToolPose) -> None:
    assert (a.x, a.y, a.z) == pytest.approx((b.x, b.y, b.z), abs=1e-9)
    assert abs(wrap_angle(a.pitch - b.pitch)) < 1e-9
    assert abs(wrap_angle(a.roll - b.roll)) < 1e-9


def test_stretched_out_arm() -> None:
    pose = forward(GEOMETRY, [0, 0, 0, 0, 0])
    reach = GEOMETRY.upper_arm + GEOMETRY.forearm + GEOMETRY.tool_length
    assert (pose.x, pose.y, pose.z, pose.pitch) == pytest.approx((reach, 0.0, GEOMETRY.shoulder_height, 0.0))


@settings(max_examples=300, deadline=None)
@given(st.tuples(*(st.floats(lo, hi) for lo, hi in zip(GEOMETRY.lower, GEOMETRY.upper, strict=True))))
def test_forward_of_inverse_is_the_pose(joints: tuple[float, ...]) -> None:
    pose = forward(GEOMETRY, joints)
    try:
        solution = inverse(GEOMETRY, pose)
    except UnreachableError:
        return  # the pose needs the other base yaw branch or a joint beyond its limit
    limits = zip(solution, GEOMETRY.lower, GEOMETRY.upper, strict=True)
    assert all(lo - 1e-9 <= q <= hi + 1e-9 for q, lo, hi in limits)
    assert_same_pose(forward(GEOMETRY, solution), pose)


@settings(max_examples=200, deadline=None)
@given(st.floats(0.12, 0.27), st.floats(-1.2, 1.2), st.floats(-0.06, 0.04), st.floats(-math.pi, math.pi))
def test_top_down_grasps_reach_the_floor_in_front_of_the_arm(reach, bearing, z, yaw) -> None:
    x, y = reach * math.cos(bearing), reach * math.sin(bearing)
    joints = top_down_grasp(GEOMETRY, x, y, z, yaw)
    pose = forward(GEOMETRY, joints)
    assert (pose.x, pose.y, pose.z) == pytest.approx((x, y, z), abs=1e-9)
    assert pose.pitch == pytest.approx(DOWN)
    # the fingers close across the grasp yaw (a parallel gripper: modulo pi)
    assert abs(math.remainder(pose.grasp_yaw() - yaw, math.pi)) < 1e-9
    rotation = tool_rotation(joints)
    assert rotation[:, 0] == pytest.approx([0, 0, -1], abs=1e-9)  # pointing down
    closing = math.atan2(rotation[1, 1], rotation[0, 1])
    assert abs(math.remainder(closing - (yaw + math.pi / 2), math.pi)) < 1e-9


def test_an_exact_grasp_yaw_is_kept_when_flipping_is_not_allowed() -> None:
    joints = top_down_grasp(GEOMETRY, 0.2, 0.0, 0.0, 2.5, allow_flip=False)
    assert forward(GEOMETRY, joints).grasp_yaw() == pytest.approx(2.5)
    flipped = top_down_grasp(GEOMETRY, 0.2, 0.0, 0.0, 2.5)
    assert abs(flipped[4]) < abs(joints[4])  # the smaller roll, turned by pi


def test_unreachable_poses_say_why() -> None:
    with pytest.raises(UnreachableError, match="outside the arm's reach"):
        top_down_grasp(GEOMETRY, 0.6, 0.0, 0.0, 0.0)
    with pytest.raises(UnreachableError, match="base's axis"):
        inverse(GEOMETRY, ToolPose(0.0, 0.0, 0.1, DOWN, 0.0))
    narrow = ArmGeometry(lower=(-2.6, -1.6, -2.6, -0.1, -2.6), upper=(2.6, 2.0, 2.6, 0.1, 2.6))
    with pytest.raises(UnreachableError, match="wrist_pitch"):
        top_down_grasp(narrow, 0.2, 0.0, 0.0, 0.0)


def test_geometry_validation() -> None:
    with pytest.raises(ValueError, match="forearm"):
        ArmGeometry(forearm=0.0).validate()
    assert np.allclose(tool_rotation([0, 0, 0, 0, 0]), np.eye(3))
