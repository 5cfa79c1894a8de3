"""The simulated physical structure, robot timing and fault injection (ROS-free)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import STRUCTURES

from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.structure_file import load_structure
from tiling_sim.faults import FaultInjector
from tiling_sim.robot_motion import (
    MotionModel,
    approach_point,
    drive_time_to_pose,
    footprint_overlaps,
    placement_phases,
    start_positions,
)
from tiling_sim.world import PhysicalWorld, PlaceCheck

PAPER = load_structure(STRUCTURES / "paper_14.yaml")


def test_placement_needs_the_supports_physically_there() -> None:
    world = PhysicalWorld(PAPER)
    check, reason = world.check_placement(4)
    assert check is PlaceCheck.SUPPORT_MISSING and "support 1, 2, 3, 6" in reason
    assert world.absent_supports(4) == [1, 2, 3, 6]
    for tile in (1, 2, 3, 6):
        world.place(tile)
    assert world.absent_supports(4) == []
    assert world.check_placement(4)[0] is PlaceCheck.OK
    world.place(4)
    assert world.check_placement(4)[0] is PlaceCheck.ALREADY_PRESENT
    assert world.check_placement(99)[0] is PlaceCheck.UNKNOWN_TILE
    with pytest.raises(ValueError):
        world.place(11)


def test_only_free_tiles_can_be_removed() -> None:
    world = PhysicalWorld(PAPER)
    for tile in (1, 2, 3, 6, 4, 9):
        world.place(tile)
    assert world.removable() == [4, 9]
    with pytest.raises(ValueError):
        world.remove(6)
    world.remove(4)
    assert 4 not in world.present and world.removable() == [1, 2, 3, 9]
    assert not world.complete()


def test_placement_phases_add_up() -> None:
    model = MotionModel(drive_speed=0.2, locate_time=1, pick_time=5, place_time=8, retreat_time=2)
    phases = placement_phases(model, (0.0, 0.0), (1.0, 0.0), (0.0, 0.5))
    assert [p.phase for p in phases] == [1, 2, 3, 4, 5, 6]
    target = approach_point(model, (0.0, 0.5), (1.0, 0.0))
    assert math.dist(target, (0.0, 0.5)) == pytest.approx(0.25)
    expected = 1.0 / 0.2 + 1 + 5 + math.dist((1.0, 0.0), target) / 0.2 + 8 + 2
    assert sum(p.duration for p in phases) == pytest.approx(expected)
    assert phases[-1].end == target


def test_box_and_polygon_overlap_by_separating_axes() -> None:
    diamond = np.array([[0.0, -1.0], [1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    assert footprint_overlaps((0.0, 0.0), (0.1, 0.1), diamond)
    assert footprint_overlaps((1.05, 0.0), (0.1, 0.1), diamond)  # the box's edge reaches the corner
    assert not footprint_overlaps((0.7, 0.7), (0.1, 0.1), diamond)  # inside the bounding box, beside the edge
    assert not footprint_overlaps((1.2, 0.0), (0.1, 0.1), diamond)


def test_a_robot_never_stands_on_the_structure() -> None:
    """With the base's footprint given, the robot stops beside the structure, as near to the tile as it can."""
    footprints = [convex_hull_2d(tile.vertices[:, :2]) for tile in PAPER.tiles.values()]
    model = MotionModel(base_size=(0.33, 0.33), base_clearance=0.03)
    half = (0.165 + 0.03, 0.165 + 0.03)
    for tile in PAPER.tiles.values():
        tile_xy = (tile.position[0], tile.position[1])
        for cache in ((1.0, -0.6), (-1.0, 0.6), (0.0, -1.0), (1.0, 0.6)):
            stop = approach_point(model, tile_xy, cache, footprints)
            assert not any(footprint_overlaps(stop, half, p) for p in footprints)
            assert math.dist(stop, tile_xy) < 0.35  # the near side, not round the far end
            without = approach_point(MotionModel(), tile_xy, cache)  # no footprint: off the tile towards the cache
            assert math.dist(without, tile_xy) == pytest.approx(0.25)
    # tile 8 sits at the +x end: a robot coming from the octagon cache (+x, -y) used to stand on tile 7
    stop = approach_point(model, (0.125, 0.0), (1.0, -0.6), footprints)
    assert not footprint_overlaps(stop, half, footprints[7 - 1])


def test_drive_time_turns_then_drives() -> None:
    model = MotionModel(drive_speed=0.5, turn_speed=1.0)
    assert drive_time_to_pose(model, (0, 0, 0), (1, 0, 0)) == pytest.approx(2.0)
    assert drive_time_to_pose(model, (0, 0, 0), (0, 0, math.pi / 2)) == pytest.approx(math.pi / 2)
    assert drive_time_to_pose(model, (0, 0, 0), (0, 1, 0)) == pytest.approx(math.pi + 2.0)


def test_faults_are_reproducible_from_the_seed() -> None:
    a = FaultInjector.scheduled(7, 3, (10.0, 100.0), drop_probability=0.3)
    b = FaultInjector.scheduled(7, 3, (10.0, 100.0), drop_probability=0.3)
    assert a.removal_times == b.removal_times and len(a.removal_times) == 3
    assert all(10.0 <= t <= 100.0 for t in a.removal_times)
    assert [a.choose([4, 9, 12]) for _ in range(5)] == [b.choose([4, 9, 12]) for _ in range(5)]
    assert [a.drops() for _ in range(20)] == [b.drops() for _ in range(20)]
    assert FaultInjector.scheduled(8, 3, (10.0, 100.0)).removal_times != a.removal_times


def test_removals_come_due_in_order() -> None:
    faults = FaultInjector(seed=1, removal_times=[50.0, 20.0])
    assert faults.due(10.0) == 0
    assert faults.due(30.0) == 1
    faults.removed()
    assert faults.due(30.0) == 0 and faults.due(60.0) == 1
    assert faults.choose([]) is None


def test_automatic_start_positions_lie_outside_the_structure_and_apart() -> None:
    centres = [(float(t.position[0]), float(t.position[1])) for t in PAPER.tiles.values()]
    starts = start_positions(centres, 4, clearance=0.6)
    assert len(starts) == 4
    for x, y in starts:
        assert min(math.hypot(x - cx, y - cy) for cx, cy in centres) >= 0.6 - 1e-9
    assert min(math.dist(a, b) for a, b in itertools.combinations(starts, 2)) > 0.5
