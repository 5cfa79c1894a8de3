"""The simulated physical structure, robot timing and fault injection (ROS-free)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import STRUCTURES

from tiling_assembly.geometry import turn_symmetry
from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.structure_file import load_structure
from tiling_sim.faults import FaultInjector, choose_wrong_tiles, mistaken_type
from tiling_sim.robot_motion import (
    MotionModel,
    approach_point,
    drive_time_to_pose,
    footprint_overlaps,
    placement_phases,
    removal_phases,
    start_positions,
)
from tiling_sim.world import Misplacement, PhysicalWorld, PlaceCheck
from tiling_sim.world_referee import Outcome as RefereeOutcome
from tiling_sim.world_referee import WorldReferee

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
    at_cache = (0.75, 0.0)  # an arm's reach short of the cache, on the side the robot comes from
    assert phases[0].end == pytest.approx(at_cache) and phases[2].end == pytest.approx(at_cache)
    expected = 0.75 / 0.2 + 1 + 5 + math.dist(at_cache, target) / 0.2 + 8 + 2
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


def test_the_clock_stops_at_each_removal_not_yet_due() -> None:
    faults = FaultInjector(seed=1, removal_times=[50.0, 20.0])
    assert faults.next_removal_after(10.0) == 20.0
    assert faults.next_removal_after(20.0) == 50.0  # at 20 s it is due: the clock may run on to the next
    faults.removed()
    faults.removed()
    assert faults.next_removal_after(10.0) is None


def test_automatic_start_positions_lie_outside_the_structure_and_apart() -> None:
    centres = [(float(t.position[0]), float(t.position[1])) for t in PAPER.tiles.values()]
    starts = start_positions(centres, 4, clearance=0.6)
    assert len(starts) == 4
    for x, y in starts:
        assert min(math.hypot(x - cx, y - cy) for cx, cy in centres) >= 0.6 - 1e-9
    assert min(math.dist(a, b) for a, b in itertools.combinations(starts, 2)) > 0.5


def test_a_tile_that_lands_shifted_blocks_its_neighbour_and_is_not_complete() -> None:
    world = PhysicalWorld(PAPER)
    world.place(3, Misplacement(shift=(0.0, 0.03)))  # the middle long rectangle, 3 cm towards tile 2
    world.place(1)
    check, reason = world.check_placement(2)
    assert check is PlaceCheck.BLOCKED
    assert reason == "tile 2 cannot be placed: tile 3 lies in the way (shifted 3.0 cm)"
    assert world.wrong_tiles_in_the_way(2) == [3] and world.wrong_tiles_in_the_way(1) == []
    assert world.wrong_tiles_in_the_way(10) == []  # 10 lies above it
    real = world.actual(3)
    assert np.allclose(real.position - PAPER.tiles[3].position, [0.0, 0.03, 0.0])
    # taken off and put down right, the structure can be finished
    world.remove(3)
    assert world.misplaced == {}
    for tile in sorted(PAPER.tile_ids, key=lambda t: PAPER.layers[t]):
        if tile not in world.present:
            world.place(tile)
    assert world.complete()


def test_a_square_cannot_lie_turned_into_the_long_rectangle_it_touches() -> None:
    """Square 10 of paper_14 touches long rectangle 12 along an edge: turned 30 degrees its corner
    would be 7 mm inside the rectangle. With 12 there, it has no room to land so; lying so first,
    it is in 12's way. Turned 5 degrees (a 1.6 mm poke, placing noise) it is no obstacle."""
    world = PhysicalWorld(PAPER)
    for tile in (1, 2, 3, 7, 5, 8, 12):
        world.place(tile)
    assert not world.room_for(10, Misplacement(turn=math.radians(30.0)))
    assert world.room_for(10, Misplacement(turn=math.radians(5.0)))
    first = PhysicalWorld(PAPER)
    for tile in (1, 2, 3, 7, 5, 8):
        first.place(tile)
    first.place(10, Misplacement(turn=math.radians(30.0)))
    check, reason = first.check_placement(12)
    assert check is PlaceCheck.BLOCKED
    assert "tile 10 lies in the way (turned +30 deg)" in reason


def test_a_tile_resting_on_a_turned_tile_cannot_be_placed() -> None:
    world = PhysicalWorld(PAPER)
    for tile in (1, 2, 3):
        world.place(tile)
    # the packing is tight: a trapezoid beside the long rectangles has no room to lie turned
    assert not world.room_for(6, Misplacement(turn=math.radians(15.0)))
    with pytest.raises(ValueError, match=r"cannot land turned \+15 deg: a present tile is there"):
        world.place(6, Misplacement(turn=math.radians(15.0)))
    alone = PhysicalWorld(PAPER)
    alone.place(6, Misplacement(turn=math.radians(15.0)))
    check, reason = alone.check_placement(9)  # the square resting on it
    assert check is PlaceCheck.BLOCKED
    assert reason == "tile 9 cannot be placed: its support 6 lies wrong (turned +15 deg)"
    assert alone.wrong_tiles_in_the_way(1) == [6]  # and it takes up room the rectangles need
    real = alone.actual(6)  # turned about its own centre: the centre stays
    assert np.allclose(real.centroid, PAPER.tiles[6].centroid)
    assert math.isclose(math.remainder(real.yaw - PAPER.tiles[6].yaw - math.radians(15.0), 2 * math.pi), 0.0,
                        abs_tol=1e-9)


def test_a_wrong_tile_is_another_type_of_the_same_height_from_the_nearest_cache() -> None:
    assert mistaken_type(PAPER, "long_rectangle") == "octagon"  # trapezoid's cache is as near: by name
    assert mistaken_type(PAPER, "triangle") == "octagon"
    assert mistaken_type(load_structure(STRUCTURES / "gate_9.yaml"), "block") is None  # no other 6 cm type
    world = PhysicalWorld(PAPER)
    world.place(3, Misplacement(type_name="octagon"))
    real = world.actual(3)
    assert real.type_name == "octagon" and np.allclose(real.position, PAPER.tiles[3].position)
    assert world.misplaced[3].kind == "wrong_type" and not world.complete()


def test_wrong_tiles_are_seeded_by_tile_in_range_and_leave_removals_as_they_were() -> None:
    misplaced, wrong = choose_wrong_tiles(seed=4, structure=PAPER, misplaced=3, wrong_type=2)
    assert (misplaced, wrong) == choose_wrong_tiles(seed=4, structure=PAPER, misplaced=3, wrong_type=2)
    assert len(misplaced) == 3 and len(wrong) == 2 and not misplaced & wrong and misplaced | wrong <= set(PAPER.tiles)
    assert all(mistaken_type(PAPER, PAPER.tiles[t].type_name) for t in wrong)
    every = frozenset(PAPER.tiles)
    landings = [FaultInjector(seed=4, misplaced_tiles=every).landing(PAPER, t) for t in sorted(every)]
    for tile, landing in zip(sorted(every), landings, strict=True):
        assert landing is not None and landing.type_name is None
        if landing.turn:  # never as far as the tile's symmetry turns it back into place
            half_symmetry = math.pi / turn_symmetry(PAPER.tiles[tile])
            assert math.radians(15.0) <= abs(landing.turn) <= min(math.radians(45.0), half_symmetry)
            assert landing.shift == (0.0, 0.0)
        else:
            assert 0.02 <= math.hypot(*landing.shift) <= 0.05
    assert {landing.kind for landing in landings} == {"shift", "turn"}
    # how a tile lands depends on the seed and the tile, not on the order tiles are placed in
    backwards = FaultInjector(seed=4, misplaced_tiles=every)
    assert [backwards.landing(PAPER, t) for t in sorted(every, reverse=True)] == landings[::-1]
    wrong_only = FaultInjector(seed=4, wrong_type_tiles=frozenset({3}))
    assert [wrong_only.landing(PAPER, t) for t in (2, 3, 3)] == [None, Misplacement(type_name="octagon"), None]
    plain, with_landings = FaultInjector(seed=9), FaultInjector(seed=9, misplaced_tiles=every)
    for tile in range(1, 6):
        with_landings.landing(PAPER, tile)
    removals = [with_landings.choose(list(range(20))) for _ in range(5)]
    assert [plain.choose(list(range(20))) for _ in range(5)] == removals
    with pytest.raises(ValueError, match="both land off and be of the wrong type"):
        FaultInjector(seed=1, misplaced_tiles=frozenset({1}), wrong_type_tiles=frozenset({1}))


def test_a_placement_the_faults_pick_lands_wrong_and_a_repair_takes_it_off() -> None:
    referee = WorldReferee(PhysicalWorld(PAPER), FaultInjector(seed=2, misplaced_tiles=frozenset({6})))
    answer = referee.placing("robot1", 6)  # its first placement lands off
    assert answer.outcome is RefereeOutcome.OK
    (placed, _), (kind, landed) = answer.events
    assert (placed, kind, landed["tile"]) == ("placed", "misplaced", 6)
    assert landed["misplacement"] in ("shift", "turn")
    assert 6 in referee.world.misplaced
    # placing it again finds it there, lying wrong: the robot is told which tile is in the way
    again = referee.placing("robot2", 6)
    assert again.outcome is RefereeOutcome.BLOCKED and again.wrong_tiles == [6]
    assert referee.removing("robot1", 6).outcome is RefereeOutcome.OK
    lifted = referee.lifted("robot1", 6)
    assert lifted.outcome is RefereeOutcome.OK
    assert lifted.events == [("taken_off", {"tile": 6, "robot": "robot1", "lay_wrong": landed["misplacement"]})]
    assert 6 not in referee.world.present and not referee.world.misplaced
    assert referee.placing("robot1", 6).events == [("placed", {"tile": 6, "robot": "robot1"})]  # right this time
    assert referee.removing("robot1", 7).outcome is RefereeOutcome.NOT_THERE


def test_a_tile_rests_on_a_wrong_type_of_its_height_and_must_come_off_first() -> None:
    world = PhysicalWorld(PAPER)
    mix_up = mistaken_type(PAPER, "trapezoid")
    assert mix_up is not None
    world.place(6, Misplacement(type_name=mix_up))  # the wrong type under 9
    assert world.check_placement(9)[0] is PlaceCheck.OK  # same height: 9 can rest on it
    world.place(9)
    referee = WorldReferee(world, FaultInjector(seed=1))
    refused = referee.lifted("robot1", 6)
    assert refused.outcome is RefereeOutcome.TILE_ON_TOP and refused.resting_on_it == [9]
    assert refused.reason == "tile 6 cannot come off: tile 9 rests on it"
    assert 6 in world.present
    shifted = PhysicalWorld(PAPER)
    shifted.place(6, Misplacement(shift=(0.03, 0.0)))
    assert shifted.check_placement(9)[0] is PlaceCheck.BLOCKED and shifted.blocking(9) == [6]


def test_a_tile_with_no_room_to_land_wrong_lands_as_planned() -> None:
    world = PhysicalWorld(PAPER)
    for tile in (1, 2, 3):
        world.place(tile)
    referee = WorldReferee(world, FaultInjector(seed=1))
    referee.faults.landing = lambda structure, tile: Misplacement(turn=math.radians(15.0))  # type: ignore[method-assign]
    answer = referee.placing("robot1", 6)  # the rectangles leave a trapezoid no room to lie turned
    assert answer.events == [("placed", {"tile": 6, "robot": "robot1"})] and not world.misplaced


def test_removal_phases_go_to_the_tile_then_to_the_drop_off() -> None:
    model = MotionModel()
    phases = removal_phases(model, (1.0, 0.0), (0.0, 0.0), (-1.0, 0.0))
    assert [p.phase for p in phases] == [1, 2, 3, 4, 5, 6]
    at_tile = phases[0].end
    assert math.isclose(math.dist(at_tile, (0.0, 0.0)), model.approach_distance)
    beside_drop_off = (-1.0 + model.approach_distance, 0.0)  # coming from the tile's side
    assert phases[3].end == pytest.approx(beside_drop_off) and phases[5].end == pytest.approx(beside_drop_off)
    assert math.isclose(phases[0].duration, math.dist((1.0, 0.0), at_tile) / model.drive_speed)
