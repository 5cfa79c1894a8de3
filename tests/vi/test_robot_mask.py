"""Which points are another robot's: its grown box, and beside its own points."""

from __future__ import annotations

import numpy as np

from vi_node.pose_prior import OverheadPose
from vi_node.robot_mask import RobotMaskSettings, inside_robots, near_robot_points


def test_the_grown_box_covers_the_localization_error() -> None:
    robot = [OverheadPose(0.5, 0.0, 0.0)]
    points = np.array([[0.5 - 0.165 - 0.06, 0.0, 0.1], [0.5 - 0.165 - 0.12, 0.0, 0.1], [0.5, 0.0, 0.5]])
    assert inside_robots(points, robot, RobotMaskSettings()).tolist() == [True, False, False]


def test_a_face_on_s_a_is_the_robot_s_only_beside_the_robot_s_own_points() -> None:
    """A robot's face continues off S_a's surfaces right beside where it crosses them; a tile's
    face inside the grown box but centimetres from any robot point is the tile's."""
    robot_face = np.array([[0.30, y, z] for y in np.linspace(-0.1, 0.1, 9) for z in np.linspace(0.03, 0.3, 10)])
    on_surfaces = np.array([[0.30, 0.0, 0.02], [0.29, 0.05, 0.04], [0.24, 0.0, 0.02], [0.20, 0.0, 0.04]])

    beside = near_robot_points(on_surfaces, robot_face, reach=0.03)

    assert beside.tolist() == [True, True, False, False]
    assert near_robot_points(on_surfaces, np.zeros((0, 3)), 0.03).tolist() == [False] * 4
