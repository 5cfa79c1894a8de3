"""The scenes `vi_accuracy` judges: where the VI robot may stand in them, how far a misplacement moves a tile."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tiling_assembly.geometry import PlacedTile, rotation_from_rpy
from tiling_assembly.structure_file import load_structure
from tiling_sim.inspection_scenarios import outline_moved, ring_of_views, structure_path, view_from
from tiling_sim.kinect import ClutterBox, KinectScene, KinectSimulator

BOX = ClutterBox((0.0, 1.0, 0.15), (0.32, 0.32, 0.30), 0.0)  # a box on the floor no overhead camera reports


def test_the_vi_robot_does_not_stand_on_a_box_nobody_reports_and_still_does_not_report_it() -> None:
    view = view_from(np.zeros(3), math.pi / 2, 1.0, np.random.default_rng(3), obstacles=(BOX,))
    assert math.hypot(view.base[0] - BOX.center[0], view.base[1] - BOX.center[1]) > 0.3
    assert view.robots == ()


def test_a_ring_of_views_around_such_a_box_never_looks_at_it_from_within_the_kinects_range() -> None:
    views = ring_of_views(np.zeros(3), np.random.default_rng(4), 12, 1.0, obstacles=(BOX,))
    simulator = KinectSimulator(seed=4)
    for view in views:
        cloud = simulator.scan(KinectScene(clutter=[BOX]), view.camera)
        assert np.isfinite(cloud[..., 2]).any(), f"view from {view.base} sees nothing at all"


def test_without_the_box_given_a_view_may_stand_on_it() -> None:
    """The check above could fail: the same bearing without the obstacle puts the base inside it."""
    view = view_from(np.zeros(3), math.pi / 2, 1.0, np.random.default_rng(3))
    assert math.hypot(view.base[0] - BOX.center[0], view.base[1] - BOX.center[1]) < 0.05


def _turned(tile: PlacedTile, degrees: float) -> PlacedTile:
    spin = rotation_from_rpy(0.0, 0.0, math.radians(degrees))
    centre = tile.vertices.mean(axis=0)
    position = spin @ (tile.position - centre) + centre
    return PlacedTile(tile.tile_id, tile.type_name, tile.shape, spin @ tile.rotation, position)


def test_a_turned_octagon_moves_its_outline_by_millimetres_a_turned_long_rectangle_by_centimetres() -> None:
    paper = load_structure(structure_path("paper_14"))
    by_type = {tile.type_name: tile for tile in paper.tiles.values()}
    assert 0.003 < outline_moved(by_type["octagon"], _turned(by_type["octagon"], 22.0)) < 0.005
    assert outline_moved(by_type["long_rectangle"], _turned(by_type["long_rectangle"], 15.0)) > 0.02
    square = by_type["square"]
    shifted = PlacedTile(square.tile_id, square.type_name, square.shape, square.rotation,
                         square.position + np.array([0.0, 0.02, 0.0]))
    assert outline_moved(square, shifted) == pytest.approx(0.02, abs=1e-6)
    assert outline_moved(square, square) == 0.0
