"""The planner's base stops (tiling_assembly.base_stops, on a grid) against the simulated robots'
(tiling_sim.robot_motion.approach_point, exact polygons): the time model charges the drives the
simulated robots make."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import STRUCTURES

from tiling_assembly.base_stops import BaseGeometry, approach_stops
from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.structure_file import load_structure
from tiling_sim.robot_motion import MotionModel, approach_point


@pytest.mark.parametrize("name, every", [("pyramid_91", 3), ("arcade_294", 12)])
def test_the_stops_are_the_simulated_robots_within_two_centimetres(name: str, every: int) -> None:
    structure = load_structure(STRUCTURES / f"{name}.yaml")
    geometry = BaseGeometry(approach_distance=0.25, base_size=(0.33, 0.33), clearance=0.03)
    motion = MotionModel(approach_distance=0.25, base_size=(0.33, 0.33), base_clearance=0.03)
    caches = np.array([structure.caches[t.type_name] for t in structure.tiles.values()], dtype=float)
    stops = approach_stops(structure, caches, geometry)
    outlines = [convex_hull_2d(t.vertices[:, :2]) for t in structure.tiles.values()]
    tiles = list(structure.tiles.values())
    boxed_in = 0
    for k in range(0, len(tiles), every):
        centre = (float(tiles[k].centroid[0]), float(tiles[k].centroid[1]))
        simulated = approach_point(motion, centre, tuple(caches[k]), outlines)
        assert math.dist(simulated, stops[k]) <= 0.03, tiles[k].tile_id
        # what the time model charges: the drive from the cache
        assert abs(math.dist(simulated, caches[k]) - math.dist(stops[k], caches[k])) <= 0.02
        boxed_in += math.dist(simulated, centre) > 0.26
    assert boxed_in >= 3  # some stops had to go round or out of the structure
