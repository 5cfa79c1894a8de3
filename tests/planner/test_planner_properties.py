"""Property tests on random valid structures: every plan is valid, trading keeps regions connected
and never makes the imbalance worse."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from planner_checks import plan_problems, region_is_connected

from planner_node.assembly_graph import build_graph
from planner_node.initial_allocation import initial_allocation
from planner_node.layer_partition import layer_partition
from planner_node.node_trading import centroid_affinity, imbalance, trade_nodes, workloads
from planner_node.planner import Method, default_robot_names, plan_assembly, replan_assembly
from planner_node.structure_generators import bridge, pyramid, random_cluster, wall
from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import parse_structure
from tiling_assembly.time_model import TimeModel

TIME_MODEL = TimeModel()
SETTINGS = settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def separate_piles(sizes: list[int], seed: int) -> dict:
    """Random piles side by side with gaps between them: a structure in several pieces."""
    document = random_cluster(sizes[0], seed=seed)
    tiles = list(document["tiles"])
    for k, size in enumerate(sizes[1:], start=1):
        for tile in random_cluster(size, seed=seed + k)["tiles"]:
            x, y, z = tile["position"]
            tiles.append({**tile, "id": len(tiles) + 1, "position": [x + 1.0 * k, y, z]})
    return {**document, "tiles": tiles}


@st.composite
def structures(draw: st.DrawFn) -> Structure:
    kind = draw(st.sampled_from(["cluster", "cluster", "piles", "wall", "pyramid", "bridge"]))
    size = draw(st.integers(min_value=4, max_value=60))
    if kind == "cluster":
        document = random_cluster(size, seed=draw(st.integers(0, 10_000)))
    elif kind == "piles":
        sizes = draw(st.lists(st.integers(2, 25), min_size=2, max_size=4))
        document = separate_piles(sizes, draw(st.integers(0, 10_000)))
    else:
        document = {"wall": wall, "pyramid": pyramid, "bridge": bridge}[kind](size)
    return parse_structure(document, f"{kind}-{size}")


def _index_sets(graph, owner: np.ndarray, n_robots: int) -> list[list[int]]:
    return [[int(graph.tile_ids[k]) for k in np.flatnonzero(owner == r)] for r in range(n_robots)]


@SETTINGS
@given(structure=structures(), n_robots=st.integers(1, 7), method=st.sampled_from(list(Method)))
def test_every_plan_is_valid(structure: Structure, n_robots: int, method: Method) -> None:
    robots = default_robot_names(n_robots)
    plan = plan_assembly(structure, robots, TIME_MODEL, method, improve_time_limit=0.05)
    assert plan_problems(structure, plan.orders(), TIME_MODEL) == []
    assert plan.schedule.completed
    assert plan.makespan >= plan.lower_bound - 1e-6
    assert plan.makespan >= plan.bound.tile_count - 1e-6
    team_model = TIME_MODEL.for_team(structure, n_robots)  # robots crowding the caches
    for task, timeline in zip(plan.tasks, plan.schedule.robots, strict=True):
        assert task.workload == pytest.approx(team_model.workload(structure, task.tile_ids))
        assert timeline.finish == pytest.approx(task.workload + task.wait)
    assert plan.makespan == pytest.approx(max(t.estimated_finish for t in plan.tasks))


@SETTINGS
@given(structure=structures(), n_robots=st.integers(1, 7))
def test_default_method_without_helping_keeps_every_region_connected(
    structure: Structure, n_robots: int
) -> None:
    robots = default_robot_names(n_robots)
    plan = plan_assembly(structure, robots, TIME_MODEL, improve_time_limit=0.05, help_neighbours=False)
    assert plan_problems(structure, plan.orders(), TIME_MODEL) == []
    assert plan.stats.helped == 0
    for task in plan.tasks:
        assert region_is_connected(structure, task.tile_ids)


@SETTINGS
@given(structure=structures(), n_robots=st.integers(1, 7))
def test_trading_keeps_regions_connected_and_never_worsens_the_imbalance(
    structure: Structure, n_robots: int
) -> None:
    graph = build_graph(structure, TIME_MODEL)
    allocation = initial_allocation(graph, n_robots)
    sliced = layer_partition(graph, n_robots)
    for owner, affinity in (
        (allocation.owner, allocation.seed_distance),
        (sliced, centroid_affinity(graph, sliced, n_robots)),
    ):
        for region in _index_sets(graph, owner, n_robots):
            assert region_is_connected(structure, region)
        traded = trade_nodes(graph, owner, n_robots, affinity)
        assert len(traded.owner) == len(graph)
        assert traded.owner.min() >= 0 and traded.owner.max() < n_robots
        for region in _index_sets(graph, traded.owner, n_robots):
            assert region_is_connected(structure, region)
        assert traded.imbalance_after <= traded.imbalance_before + 1e-12
        assert traded.workload_after.max() <= traded.workload_before.max() + 1e-9
        assert imbalance(workloads(graph, traded.owner, n_robots)) == pytest.approx(traded.imbalance_after)


@SETTINGS
@given(structure=structures(), n_robots=st.integers(1, 5), data=st.data())
def test_replanning_covers_exactly_the_tiles_not_yet_placed(
    structure: Structure, n_robots: int, data: st.DataObject
) -> None:
    placed = data.draw(st.sets(st.sampled_from(sorted(structure.tiles))))
    robots = default_robot_names(n_robots)
    plan = replan_assembly(structure, placed, robots, TIME_MODEL, improve_time_limit=0.05)
    remaining = structure.subset(t for t in structure.tiles if t not in placed)
    assert sorted(t for task in plan.tasks for t in task.tile_ids) == sorted(remaining.tiles)
    assert plan_problems(remaining, plan.orders(), TIME_MODEL) == []
    assert set(plan.supports) == set(remaining.tiles)
    assert all(plan.supports[t] == structure.supports[t] for t in remaining.tiles)
