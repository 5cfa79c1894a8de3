"""What the planner works out without scipy (its import costs the `plan` command a third of a
second) agrees with scipy to the last bit: hulls, nearest neighbours, pieces, Dijkstra."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest
from conftest import STRUCTURES
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components as scipy_components
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull, QhullError, cKDTree

from planner_node.assembly_graph import AssemblyGraph, build_graph, connected_components
from planner_node.footprint import convex_hull_indices, nearest_neighbour_distances
from planner_node.initial_allocation import initial_allocation, nearest_seed_distances
from planner_node.schedule_sim import simulate_orders
from planner_node.sequencing import Policy, sequence_tiles
from planner_node.structure_generators import GENERATORS
from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import load_structure, parse_structure
from tiling_assembly.time_model import TimeModel


def _structures() -> list[Structure]:
    structures = [load_structure(p) for p in sorted(STRUCTURES.glob("*.yaml"))]
    return structures + [parse_structure(make(n), kind) for kind, make in GENERATORS.items() for n in (40, 700)]


def _corners(structure: Structure) -> list[tuple[float, float]]:
    """Four robots standing a metre off the corners of the structure's bounds."""
    (x0, y0, _), (x1, y1, _) = structure.bounds
    return [(x0 - 1.0, y0 - 1.0), (x1 + 1.0, y0 - 1.0), (x1 + 1.0, y1 + 1.0), (x0 - 1.0, y1 + 1.0)]


GRAPHS = [build_graph(s, TimeModel()) for s in _structures()]
# the same, with the robots starting away from their caches
STARTED_GRAPHS = [replace(build_graph(s, TimeModel()), first_trip=TimeModel().start_trips(s, _corners(s)))
                  for s in _structures()]


def _point_sets() -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    ground = [g.centroids[g.layer == 0, :2] for g in GRAPHS]
    scattered = [rng.random((int(rng.integers(3, 300)), 2)) * rng.random() for _ in range(40)]
    on_a_grid = [rng.integers(0, 15, (int(rng.integers(3, 200)), 2)) * 0.05 for _ in range(40)]
    bunched_with_an_outlier = [np.vstack([rng.random((400, 2)) * 0.2, [[50.0, 40.0]]])]
    return [p for p in ground + scattered + on_a_grid + bunched_with_an_outlier if len(p) >= 2]


@pytest.mark.parametrize("points", _point_sets())
def test_hull_and_spacing_are_qhulls_and_the_kd_trees(points: np.ndarray) -> None:
    try:
        expected = points[ConvexHull(points).vertices]
    except (QhullError, ValueError):
        expected = None
    corners = convex_hull_indices(points)
    if expected is None:
        assert corners is None
    else:
        assert corners is not None
        mine = [tuple(p) for p in points[corners].tolist()]
        theirs = [tuple(p) for p in expected.tolist()]
        k = theirs.index(mine[0])  # the same corners, counter-clockwise, from another start
        assert theirs[k:] + theirs[:k] == mine
    spacing = cKDTree(points).query(points, k=2)[0][:, 1]
    assert np.array_equal(nearest_neighbour_distances(points), spacing)


@pytest.mark.parametrize("graph", GRAPHS)
def test_pieces_are_numbered_as_scipy_numbers_them(graph: AssemblyGraph) -> None:
    count, labels = scipy_components(graph.adjacency, directed=False)
    assert graph.n_components == count
    assert np.array_equal(graph.component, labels)
    # and within regions, as the layer partition's repair asks
    owner = np.arange(len(graph)) % 3
    rows, columns = graph.edge_ends
    same = owner[rows] == owner[columns]
    start = np.concatenate([[0], np.cumsum(np.bincount(rows[same], minlength=len(graph)))]).astype(np.int64)
    n = len(graph)
    inner = csr_matrix((np.ones(int(same.sum())), (rows[same], columns[same])), shape=(n, n))
    expected_count, expected = scipy_components(inner, directed=False)
    count, labels = connected_components(start, columns[same])
    assert count == expected_count
    assert np.array_equal(labels, expected)


@pytest.mark.parametrize("graph", GRAPHS)
def test_distances_to_the_nearest_seed_are_scipys(graph: AssemblyGraph) -> None:
    allocation = initial_allocation(graph, 5)
    seeds = list(allocation.seed_tiles)
    expected = dijkstra(graph.adjacency, directed=True, indices=seeds, min_only=True)
    assert np.array_equal(nearest_seed_distances(graph, seeds), expected)
    assert np.array_equal(allocation.distance, allocation.seed_distance[allocation.owner, np.arange(len(graph))])


def test_the_plan_command_plans_a_big_structure_without_importing_scipy() -> None:
    script = (
        "import sys\n"
        "from planner_node import plan_command\n"
        "from planner_node.planner import default_robot_names, plan_assembly\n"
        "from planner_node.structure_generators import pyramid\n"
        "from tiling_assembly.structure_file import parse_structure\n"
        "from tiling_assembly.time_model import TimeModel\n"
        "plan_assembly(parse_structure(pyramid(2500), 'p'), default_robot_names(4), TimeModel())\n"
        "print(sorted({m.split('.')[0] for m in sys.modules} & {'scipy', 'networkx', 'rclpy'}))\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    assert run.stdout.strip() == "[]"


@pytest.mark.parametrize("structure", [load_structure(p) for p in sorted(STRUCTURES.glob("*.yaml"))]
                         + [parse_structure(GENERATORS["cluster"](500), "cluster")])
def test_the_graphs_layers_and_dependents_are_the_structures(structure: object) -> None:
    """The graph works them out by index, without the structure's dictionaries."""
    graph = build_graph(structure, TimeModel())
    ids = graph.tile_ids.tolist()
    assert graph.layer.tolist() == [structure.layers[t] for t in ids]
    assert [tuple(ids[d] for d in deps) for deps in graph.dependent_lists] == [structure.supported_by[t] for t in ids]


@pytest.mark.parametrize("graph", GRAPHS + STARTED_GRAPHS)
def test_a_pass_without_delays_is_its_own_simulation(graph: AssemblyGraph) -> None:
    """Sequencings that give their schedule give exactly what simulating their orders gives, also
    when the robots drive to their first caches from elsewhere."""
    owner = initial_allocation(graph, 4).owner
    for policy, margin in ((Policy.CRITICAL_PATH, None), (Policy.MAX_SLACK, None), (Policy.CRITICAL_PATH, 0.0),
                           (Policy.CRITICAL_PATH, 10.0)):
        sequencing = sequence_tiles(graph, owner, 4, policy, None, margin)
        if sequencing.schedule is None:
            continue
        simulated = simulate_orders(graph, sequencing.orders)
        for name in ("start", "arrive", "place_start", "place_end", "finish", "robot_busy", "robot_wait",
                     "robot_finish"):
            assert np.array_equal(getattr(sequencing.schedule, name), getattr(simulated, name)), name
        assert sequencing.schedule.blocked == simulated.blocked


def test_pieces_of_long_chains_and_random_graphs_are_scipys() -> None:
    """Also where node numbers run across a chain at random (hooking, not label spreading)."""
    rng = np.random.default_rng(8)
    edge_lists = [(5000, rng.permutation(5000)), (7, np.arange(0))]
    for _ in range(20):
        n = int(rng.integers(1, 800))
        edge_lists.append((n, rng.integers(0, n, 2 * int(rng.integers(0, 2 * n)))))
    for n, ends in edge_lists:
        a, b = (ends[:-1], ends[1:]) if len(ends) == n else (ends[0::2], ends[1::2])
        a, b = a[a != b], b[a != b]
        matrix = csr_matrix((np.ones(2 * len(a)), (np.concatenate([a, b]), np.concatenate([b, a]))), shape=(n, n))
        matrix.sum_duplicates()
        matrix.sort_indices()
        count, labels = connected_components(matrix.indptr.astype(np.int64), matrix.indices.astype(np.int64))
        expected_count, expected = scipy_components(matrix, directed=False)
        assert count == expected_count
        assert np.array_equal(labels, expected)
