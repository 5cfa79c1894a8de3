"""The team simulation and the lower bound on hand-computed cases; seeds and trading details."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import STRUCTURES
from scipy.sparse.csgraph import connected_components

from planner_node.assembly_graph import build_graph
from planner_node.initial_allocation import exterior_seeds, initial_allocation
from planner_node.makespan_bound import makespan_lower_bound
from planner_node.node_trading import RegionBorders
from planner_node.planner import PlanningError, plan_assembly
from planner_node.schedule_sim import simulate_plan
from planner_node.structure_generators import pyramid, random_cluster
from tiling_assembly.structure_file import load_structure, parse_structure
from tiling_assembly.time_model import TimeModel
from tiling_assembly.time_model import _stops as stops_of

TIMES = TimeModel(  # trips centre to centre
    pick_time=5.0, place_time=10.0, travel_speed=0.5, cache_standoff=0.0, approach_distance=0.0, base_size=(0.0, 0.0),
    base_clearance=0.0,
)


def _box(length: float, width: float, height: float) -> dict:
    hx, hy = length / 2, width / 2
    return {"prism": {"polygon": [[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]], "height": height}}


def arch() -> object:
    """Blocks 1 and 2 side by side on the floor, beam 3 resting on both."""
    return parse_structure(
        {
            "tile_types": {"block": _box(0.1, 0.1, 0.05), "beam": _box(0.2, 0.1, 0.05)},
            "tiles": [
                {"id": 1, "type": "block", "position": [0.0, 0.0, 0.0]},
                {"id": 2, "type": "block", "position": [0.1, 0.0, 0.0]},
                {"id": 3, "type": "beam", "position": [0.05, 0.0, 0.05]},
            ],
            "caches": {"block": [0.0, -1.0], "beam": [0.05, 1.0]},
        },
        "arch",
    )


def two_stacks() -> object:
    """Two separate stacks: 3 on 1, 4 on 2."""
    return parse_structure(
        {
            "tile_types": {"block": _box(0.1, 0.1, 0.05)},
            "tiles": [
                {"id": 1, "type": "block", "position": [0.0, 0.0, 0.0]},
                {"id": 2, "type": "block", "position": [0.3, 0.0, 0.0]},
                {"id": 3, "type": "block", "position": [0.0, 0.0, 0.05]},
                {"id": 4, "type": "block", "position": [0.3, 0.0, 0.05]},
            ],
            "caches": {"block": [0.0, -1.0]},
        },
        "stacks",
    )


B_TRAVEL = math.hypot(0.1, 1.0) / 0.5  # s, one way between the block cache and block 2


def back_from(x: float) -> float:
    """Seconds from a tile of the arch at (x, 0) back to a cache: the block cache (used by two tiles)
    two times in three, the beam cache once."""
    return (2 * math.hypot(x, 1.0) + math.hypot(x - 0.05, 1.0)) / 3 / 0.5


def test_times_of_a_plan_with_next_to_no_waiting() -> None:
    schedule = simulate_plan(arch(), TIMES, {"robot1": [1, 3], "robot2": [2]})
    assert schedule.completed
    one, three = schedule.robots[0].tiles
    # robot1 starts at the block cache: pick 5 s, carry 2 s, place 10 s, walk back to a cache ~2 s
    times = (one.start, one.arrive, one.place_start, one.place_end, one.finish)
    assert times == pytest.approx((0, 7, 7, 17, 17 + back_from(0.0)))
    # then the beam: its supports are placed at 17 s and 17.01 s; robot1 sets out for it once the
    # second is there (it stood 0.01 s by block 1), walks back to the beam cache and picks it
    second_support = 5 + B_TRAVEL + 10
    assert schedule.timing(2).place_end == pytest.approx(second_support)
    beam_start = second_support + back_from(0.0)
    assert (three.start, three.arrive, three.place_start) == pytest.approx((beam_start, beam_start + 7,
                                                                            beam_start + 7))
    assert three.finish == pytest.approx(beam_start + 17 + back_from(0.05))
    assert three.wait == pytest.approx(second_support - 17)
    assert schedule.makespan == pytest.approx(three.finish)
    assert schedule.total_wait == pytest.approx(second_support - 17)


def test_a_robot_waits_for_a_support_placed_by_another() -> None:
    schedule = simulate_plan(arch(), TIMES, {"robot1": [3], "robot2": [1, 2]})
    beam = schedule.timing(3)
    last_support = 17 + back_from(0.0) + 5 + B_TRAVEL + 10  # robot2 places block 2 after block 1
    assert schedule.timing(2).place_end == pytest.approx(last_support)
    # robot1 stands at the beam cache until then (its goal is sent once the supports are placed)
    assert beam.start == pytest.approx(last_support)
    assert beam.arrive == beam.place_start == pytest.approx(last_support + 7.0)
    assert beam.wait == pytest.approx(last_support)
    robot1 = schedule.robots[0]
    assert robot1.busy == pytest.approx(TIMES.tile_cost(arch(), 3))
    assert robot1.finish == pytest.approx(robot1.busy + robot1.wait)
    assert schedule.makespan == pytest.approx(last_support + 7.0 + 10.0 + back_from(0.05))


def test_contradictory_orders_deadlock_and_name_the_blocked_tiles() -> None:
    own = simulate_plan(arch(), TIMES, {"robot1": [3, 1], "robot2": [2]})
    assert not own.completed
    assert own.blocked_tiles == (3,)
    crossed = simulate_plan(two_stacks(), TIMES, {"robot1": [3, 2], "robot2": [4, 1]})
    assert not crossed.completed
    assert sorted(crossed.blocked_tiles) == [3, 4]
    assert crossed.robots[0].tiles == () and crossed.robots[1].tiles == ()


def test_bad_orders_are_refused() -> None:
    with pytest.raises(ValueError, match="more than once"):
        simulate_plan(arch(), TIMES, {"robot1": [1, 3], "robot2": [1, 2]})
    with pytest.raises(ValueError, match="not a tile"):
        simulate_plan(arch(), TIMES, {"robot1": [1, 9]})


def test_lower_bound_of_the_arch() -> None:
    graph = build_graph(arch(), TIMES)
    bound = makespan_lower_bound(graph, 2)
    # the chain block 2 -> beam: pick + carry block 2, place it; then set out for the beam: pick and
    # carry it (7 s), place it, walk back
    assert bound.critical_path == pytest.approx(5 + B_TRAVEL + 10 + 7 + 10 + back_from(0.05))
    assert bound.work_per_robot == pytest.approx(sum(TIMES.tile_cost(arch(), t) for t in (1, 2, 3)) / 2)
    assert bound.value == pytest.approx(max(bound.critical_path, bound.work_per_robot))
    cheapest = sorted(TIMES.tile_cost(arch(), t) for t in (1, 2, 3))[:2]
    assert bound.tile_count == pytest.approx(sum(cheapest))  # one robot places two tiles
    assert makespan_lower_bound(graph, 1).value == pytest.approx(graph.total_work)


def test_graph_costs_are_the_time_models() -> None:
    structure = load_structure(STRUCTURES / "paper_14.yaml")
    graph = build_graph(structure, TimeModel())
    for k, tile in enumerate(graph.tile_ids):
        assert graph.cost[k] == pytest.approx(TimeModel().tile_cost(structure, int(tile)))
        assert graph.pick[k] + graph.travel[k] + graph.place[k] + graph.back[k] == pytest.approx(graph.cost[k])
    assert graph.n_components == 1


def test_robots_beyond_one_per_cache_make_every_pick_dearer() -> None:
    """The measured interference cost: pyramid_91's tiles use 2 caches; 2 robots crowd neither,
    4 robots are one too many at each, 3 half a robot; paper_14's 5 caches take 2 robots freely."""
    pyramid_91 = load_structure(STRUCTURES / "pyramid_91.yaml")
    paper = load_structure(STRUCTURES / "paper_14.yaml")
    model = TimeModel(cache_crowding=4.0, stop_crowding=0.0)
    assert model.for_team(pyramid_91, 2).crowding_time == 0.0
    assert model.for_team(pyramid_91, 3).crowding_time == pytest.approx(2.0)
    assert model.for_team(pyramid_91, 4).crowding_time == pytest.approx(4.0)
    assert model.for_team(paper, 2).crowding_time == 0.0
    crowded = model.for_team(pyramid_91, 4)
    assert crowded.for_team(pyramid_91, 4) == crowded  # not charged twice
    tile = pyramid_91.tile_ids[0]
    assert crowded.tile_cost(pyramid_91, tile) == pytest.approx(model.tile_cost(pyramid_91, tile) + 4.0)
    graph = build_graph(pyramid_91, crowded)
    assert graph.pick[0] == pytest.approx(crowded.pick_time + 4.0)
    assert graph.cost[0] == pytest.approx(crowded.tile_cost(pyramid_91, int(graph.tile_ids[0])))
    with pytest.raises(ValueError, match="cache_crowding"):
        TimeModel(cache_crowding=-1.0)


def test_robots_meeting_beside_a_small_structure_make_every_pick_dearer() -> None:
    """The other measured interference cost: beside paper_14 (30 cm, smaller than two bases) a base
    at one stop overlaps 44% of the others; with caches to spare it is what the team pays. The
    larger of the two crowdings counts, and one robot pays neither."""
    paper = load_structure(STRUCTURES / "paper_14.yaml")
    pyramid_91 = load_structure(STRUCTURES / "pyramid_91.yaml")
    arcade = load_structure(STRUCTURES / "arcade_294.yaml")
    model = TimeModel(cache_crowding=3.5, stop_crowding=4.5)
    assert model.stop_share(paper) == pytest.approx(0.44, abs=0.01)
    assert model.stop_share(arcade) < 0.1 < model.stop_share(pyramid_91) < model.stop_share(paper)
    assert model.for_team(paper, 1).crowding_time == 0.0
    assert model.for_team(paper, 2).crowding_time == pytest.approx(4.5 * model.stop_share(paper))
    assert model.for_team(paper, 3).crowding_time == pytest.approx(2 * 4.5 * model.stop_share(paper))
    assert model.for_team(arcade, 8).crowding_time == pytest.approx(3.5 * 3)  # 8 robots on 2 caches
    wide = TimeModel(base_size=(0.6, 0.6))
    assert wide.stop_share(paper) > model.stop_share(paper)
    with pytest.raises(ValueError, match="stop_crowding"):
        TimeModel(stop_crowding=-1.0)


@pytest.mark.parametrize(
    "make", [lambda: pyramid(1500), lambda: random_cluster(1200, seed=4)], ids=["pyramid", "cluster"]
)
def test_the_stop_share_counts_every_overlapping_stop(make) -> None:  # type: ignore[no-untyped-def]
    """The share, counted in x windows of the sorted stops (10k tiles: 8 ms, not 190), against
    every probe compared with every stop."""
    structure = parse_structure(make(), "generated")
    model = TimeModel()
    base = model.base()
    stops = stops_of(structure, base)[0]
    probes = stops[:: max(1, len(stops) // 512)]
    reach = np.asarray(base.base_size) + base.clearance
    overlapping = np.all(np.abs(probes[:, None, :] - stops[None, :, :]) < reach, axis=-1).sum() - len(probes)
    assert model.stop_share(structure) == pytest.approx(overlapping / (len(probes) * (len(stops) - 1)), rel=1e-12)


def test_seeds_are_spread_along_the_exterior_of_a_pyramid() -> None:
    structure = parse_structure(pyramid(91), "pyramid")
    graph = build_graph(structure, TimeModel())
    ground = np.flatnonzero(graph.layer == 0)
    seeds = exterior_seeds(graph, np.arange(len(graph)), 4)
    assert len(set(seeds)) == 4 and set(seeds) <= set(ground.tolist())
    xy = graph.centroids[seeds, :2]
    low, high = graph.centroids[ground, :2].min(axis=0), graph.centroids[ground, :2].max(axis=0)
    on_edge = np.isclose(xy, low) | np.isclose(xy, high)
    assert on_edge.any(axis=1).all()  # every seed on the footprint's outline
    angles = np.degrees(np.arctan2(*(xy - xy.mean(axis=0)).T[::-1]))
    gaps = np.diff(np.sort(angles))
    assert gaps.min() > 45  # spread around the structure, one per side
    # robot 1 starts on the left
    assert xy[0, 0] == pytest.approx(low[0])


def test_dijkstra_regions_are_trees_around_their_seeds() -> None:
    structure = parse_structure(random_cluster(200, seed=3), "cluster")
    graph = build_graph(structure, TimeModel())
    allocation = initial_allocation(graph, 5)
    for r, seed in enumerate(allocation.seeds):
        assert allocation.owner[seed] == r
        members = np.flatnonzero(allocation.owner == r)
        count, _ = connected_components(graph.adjacency[members][:, members], directed=False)
        assert count == len(set(graph.component[members].tolist()))
    assert np.all(allocation.distance <= allocation.seed_distance.min(axis=0) + 1e-12)


def test_the_local_connectivity_check_never_splits_a_region() -> None:
    structure = parse_structure(random_cluster(300, seed=11), "cluster")
    graph = build_graph(structure, TimeModel())
    owner = initial_allocation(graph, 4).owner
    regions = RegionBorders(graph, owner, 4)
    answers = []
    for tile in range(len(graph)):
        region = owner[tile]
        keep = np.flatnonzero(owner == region)
        keep = keep[keep != tile]
        if len(keep) == 0:
            expected = False
        else:
            sub = graph.adjacency[keep][:, keep]
            pieces = len(set(graph.component[keep].tolist()))
            expected = connected_components(sub, directed=False)[0] == pieces
        answer = regions.can_leave(tile)
        assert expected or not answer, f"tile {tile} may leave but its region would split"
        answers.append(answer == expected)
    # the search gives up (says no) only past its budget, which these small regions rarely reach
    assert sum(answers) >= 0.95 * len(answers)


def test_a_tile_refused_leave_is_asked_again_once_a_neighbour_has_moved() -> None:
    # four blocks in a row: the contact graph is the path 0-1-2-3
    structure = parse_structure(
        {
            "tile_types": {"block": _box(0.1, 0.1, 0.05)},
            "tiles": [{"id": i + 1, "type": "block", "position": [0.1 * i, 0.0, 0.0]} for i in range(4)],
            "caches": {"block": [0.0, -1.0]},
        },
        "row",
    )
    graph = build_graph(structure, TimeModel())
    regions = RegionBorders(graph, np.array([0, 0, 0, 1]), 2)
    assert not regions.can_leave(1)  # tiles 0 and 2 would be cut apart
    assert not regions.can_leave(1)  # remembered
    regions.move(0, 1)
    assert regions.can_leave(1)  # its neighbour left: only tile 2 is left beside it


def test_a_trip_starts_an_arms_reach_short_of_the_cache() -> None:
    structure = arch()
    paper = TimeModel(cache_standoff=0.0, approach_distance=0.0, base_size=(0.0, 0.0), base_clearance=0.0)
    short = replace(paper, cache_standoff=0.25)  # the base stops 0.25 m short of the cache, as the M3 does
    for tile in structure.tiles:
        d = paper.cache_distance(structure, tile)
        assert paper.travel_time(structure, tile) == pytest.approx(d / 0.15)
        assert short.travel_time(structure, tile) == pytest.approx((d - 0.25) / 0.15)
        assert short.tile_cost(structure, tile) == pytest.approx(paper.tile_cost(structure, tile) - 2 * 0.25 / 0.15)
    assert TimeModel(cache_standoff=5.0).travel_time(structure, 1) == 0.0  # never a negative trip
    with pytest.raises(ValueError, match="cache_standoff"):
        TimeModel(cache_standoff=-0.1)
    with pytest.raises(ValueError, match="base_size"):
        TimeModel(base_size=(0.3, -0.1))


def test_the_base_stops_an_arms_reach_off_the_tile_or_clear_of_the_structure() -> None:
    """A row of three blocks with their cache straight ahead of block 1: an arm's reach off block 1
    towards the cache the base stands clear. Blocks 2 and 3 have their neighbours on that side: the
    base turns round the tile (5 degree steps) until its footprint clears the row, 0.25 m sin(turn)
    >= 0.05 m (the tiles' half width) + 0.15 m (half the base) + 0.02 m (clearance): 65 degrees."""
    row = parse_structure(
        {
            "tile_types": {"block": _box(0.1, 0.1, 0.05)},
            "tiles": [{"id": k + 1, "type": "block", "position": [0.1 * k, 0.0, 0.0]} for k in range(3)],
            "caches": {"block": [-2.0, 0.0]},
        },
        "row",
    )
    model = TimeModel(cache_standoff=0.0, approach_distance=0.25, base_size=(0.3, 0.3), base_clearance=0.02)
    assert model.travel_time(row, 1) == pytest.approx(1.75 / 0.15, abs=0.01 / 0.15)
    turn = math.radians(65.0)
    for tile, x in ((2, 0.1), (3, 0.2)):
        stop = (x - 0.25 * math.cos(turn), 0.25 * math.sin(turn))
        assert model.travel_time(row, tile) == pytest.approx(math.hypot(stop[0] + 2.0, stop[1]) / 0.15,
                                                             abs=0.02 / 0.15)
    # a subset (the tiles left to build) still has its base stops clear of all the tiles
    assert model.travel_time(row.subset([2, 3]), 2) == pytest.approx(model.travel_time(row, 2))
    free = TimeModel(cache_standoff=0.0, approach_distance=0.25, base_size=(0.0, 0.0), base_clearance=0.0)
    assert free.travel_time(row, 3) == pytest.approx(1.95 / 0.15)  # a point robot stands among the tiles


def test_the_trip_back_goes_to_the_caches_in_use() -> None:
    structure = arch()
    model = TIMES
    for tile, x in ((1, 0.0), (2, 0.1), (3, 0.05)):
        assert model.return_time(structure, tile) == pytest.approx(back_from(x))
        assert model.tile_cost(structure, tile) == pytest.approx(
            model.handling_time(structure.tiles[tile].type_name) + model.travel_time(structure, tile) + back_from(x))


def test_robots_standing_away_from_their_caches_drive_there_first() -> None:
    """robot1 stands 1 m beyond the block cache (0, -1), robot2 on the beam cache (0.05, 1): robot1
    drives 1 m at 0.5 m/s before it picks, robot2 starts at once."""
    structure = arch()
    graph = replace(build_graph(structure, TIMES), first_trip=TIMES.start_trips(structure, [(0.0, -2.0), (0.05, 1.0)]))
    to_blocks, to_beam = [2.0, math.hypot(0.05, 3.0) / 0.5], [math.hypot(0.05, 2.0) / 0.5, 0.0]
    expected = [[to_blocks[0], to_blocks[0], to_blocks[1]], [to_beam[0], to_beam[0], to_beam[1]]]
    np.testing.assert_allclose(graph.first_trip, expected)
    schedule = simulate_plan(structure, TIMES, {"robot1": [1, 2], "robot2": [3]}, graph=graph)
    one = schedule.timing(1)
    assert (one.start, one.arrive) == pytest.approx((2.0, 2.0 + 5 + 2))
    robot1 = schedule.robots[0]
    assert robot1.finish == pytest.approx(2.0 + robot1.busy + robot1.wait)  # the drive is not work
    beam = schedule.timing(3)  # robot2 stands at the beam cache until block 2 is placed
    assert beam.start == pytest.approx(schedule.timing(2).place_end)
    assert beam.place_start == pytest.approx(beam.start + 7.0)


def test_a_plan_for_robots_away_from_their_caches_hands_each_the_task_that_starts_near_it() -> None:
    """paper_14's two robots stand next to the long-rectangle cache, one by the trapezoids, one by the
    octagons. The tasks are those made for robots starting at their caches (one begins with a
    trapezoid, one with a long rectangle); the robot by the trapezoids takes the first, and the
    plan's finish counts the drives."""
    paper = load_structure(STRUCTURES / "paper_14.yaml")
    starts = [(-0.6, -0.9), (0.6, -0.9)]
    at_caches = plan_assembly(paper, ["robot1", "robot2"], TimeModel())
    away = plan_assembly(paper, ["robot1", "robot2"], TimeModel(), robot_starts=starts)
    assert sorted(t.tile_ids for t in away.tasks) == sorted(t.tile_ids for t in at_caches.tasks)
    assert [paper.tiles[t.tile_ids[0]].type_name for t in away.tasks] == ["trapezoid", "long_rectangle"]
    drives = TimeModel().start_trips(paper, starts)
    ids = list(paper.tiles)
    for robot, task in enumerate(away.tasks):
        first = ids.index(task.tile_ids[0])
        assert drives[robot][first] < 3.0  # a cache within 0.7 m (the farthest is 2 m away)
        assert task.estimated_finish >= drives[robot][first] + task.workload - 1e-9
    assert at_caches.makespan <= away.makespan <= at_caches.makespan + 3.0
    with pytest.raises(PlanningError, match="3 start positions for 2 robots"):
        plan_assembly(paper, ["robot1", "robot2"], TimeModel(), robot_starts=[*starts, (0.0, 0.0)])
