"""Where an assembly robot waits with nothing left to place (assembly_node.parking), without ROS."""

from __future__ import annotations

import math

import pytest

from assembly_node.parking import Parking, facing


def test_home_is_where_the_robot_was_first_seen_unless_named() -> None:
    parking = Parking()
    parking.saw_robot_at((1.0, -0.5))
    parking.saw_robot_at((0.2, 0.1))
    assert parking.home == (1.0, -0.5)
    named = Parking(home=(2.0, 2.0))
    named.saw_robot_at((1.0, -0.5))
    assert named.home == (2.0, 2.0)


def test_an_idle_robot_away_from_home_drives_home_once_per_idle_spell() -> None:
    parking = Parking(home=(1.0, -0.5))
    assert parking.drive_home(idle=False, standing_at=(0.1, 0.0)) is None  # still has work
    assert parking.drive_home(idle=True, standing_at=(0.1, 0.0)) == (1.0, -0.5)
    parking.started()
    # the drive failed half way: it is not tried again while the robot stays idle
    assert parking.drive_home(idle=True, standing_at=(0.5, -0.2)) is None
    # work came and went: a new idle spell, a new drive
    assert parking.drive_home(idle=False, standing_at=(0.5, -0.2)) is None
    assert parking.drive_home(idle=True, standing_at=(0.3, 0.0)) == (1.0, -0.5)


def test_no_drive_when_home_or_the_robot_is_unknown_or_it_is_home_already() -> None:
    assert Parking().drive_home(idle=True, standing_at=(0.1, 0.0)) is None
    assert Parking(home=(1.0, -0.5)).drive_home(idle=True, standing_at=None) is None
    # the overhead view errs by up to 5 cm: that close is home
    assert Parking(home=(1.0, -0.5)).drive_home(idle=True, standing_at=(1.05, -0.45)) is None


def test_a_parked_robot_faces_the_structure() -> None:
    assert facing((1.0, 0.0), (0.0, 0.0)) == pytest.approx(math.pi)
    assert facing((0.0, -1.0), (0.0, 0.0)) == pytest.approx(math.pi / 2)
    assert facing((0.0, 0.0), (0.0, 0.0)) == 0.0
