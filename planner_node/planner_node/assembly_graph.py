"""The assembly graph of paper section 2.1 (after its reference [11], Worcester, Rogoff and Hsieh).

Tiles are the nodes; an undirected edge joins two tiles that touch, side by side or stacked
(`Structure.contacts`, plus every support pair), weighted by the distance between their centroids.
The precedence DAG is the support relation: a tile's supports must be placed before it. Every
tile also carries its cost phases under the time model: pick at its type's cache, carry to the
structure, place, return to a cache (`TimeModel.tile_cost` is their sum).

The planner works on array indices 0..n-1 (tiles in increasing id order); `tile_ids` maps back.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import chain, pairwise
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

MIN_EDGE_WEIGHT = 1e-9  # m: sparse graphs drop zero weights, and a zero would merge two tiles


@dataclass(frozen=True, eq=False)
class AssemblyGraph:
    """Tiles, their contacts, precedence and costs, indexed 0..n-1 in increasing tile id."""

    tile_ids: IntArray  # (n,) tile id of each index
    type_names: tuple[str, ...]  # tile type of each index
    centroids: FloatArray  # (n, 3) m
    pick: FloatArray  # (n,) s, picking the tile at its cache
    travel: FloatArray  # (n,) s, from the cache to the tile
    back: FloatArray  # (n,) s, from the tile back to a cache (TimeModel.return_time)
    place: FloatArray  # (n,) s, placing it
    cost: FloatArray  # (n,) s, TimeModel.tile_cost: pick + travel + place + back
    # the contact graph in compressed sparse rows: the neighbours of tile k are
    # neighbour_index[neighbour_start[k]:neighbour_start[k + 1]], in increasing order, at
    # neighbour_distance (centroid to centroid, m)
    neighbour_start: IntArray  # (n + 1,)
    neighbour_index: IntArray  # (2 * edges,)
    neighbour_distance: FloatArray  # (2 * edges,)
    support_lists: tuple[tuple[int, ...], ...]  # indices each tile rests on
    dependent_lists: tuple[tuple[int, ...], ...]  # indices resting on each tile
    layer: IntArray  # (n,) 0 on the floor, else one above the highest support
    component: IntArray  # (n,) connected component of the contact graph
    n_components: int
    # (robots, n) s from where each robot stands at the start to the cache of each tile's type, the
    # trip before its first tile; (0, n) when the robots start at their caches (the paper's)
    first_trip: FloatArray

    def first_trips(self, n_robots: int) -> list[list[float]]:
        """`first_trip` as lists for `n_robots` robots (zeros when the robots start at their caches)."""
        if len(self.first_trip) == 0:
            return [[0.0] * len(self)] * n_robots
        if len(self.first_trip) != n_robots:
            raise ValueError(f"the graph has start positions for {len(self.first_trip)} robots, not {n_robots}")
        return self.first_trip.tolist()

    def __len__(self) -> int:
        return len(self.tile_ids)

    @cached_property
    def index_of(self) -> dict[int, int]:
        return {int(t): k for k, t in enumerate(self.tile_ids)}

    @cached_property
    def adjacency(self) -> csr_matrix:
        """(n, n) symmetric scipy matrix of the centroid distances of touching tiles. Made when
        asked for: importing scipy.sparse costs the `plan` command a third of a second, and the
        default method on big structures does without it."""
        from scipy.sparse import csr_matrix

        n = len(self)
        return csr_matrix((self.neighbour_distance, self.neighbour_index, self.neighbour_start), shape=(n, n))

    @cached_property
    def neighbor_lists(self) -> tuple[tuple[int, ...], ...]:
        """Touching tiles of each tile (Python tuples: the trading loop indexes them one by one)."""
        ptr, idx = self.neighbour_start.tolist(), self.neighbour_index.tolist()
        return tuple(tuple(idx[ptr[k] : ptr[k + 1]]) for k in range(len(self)))

    @cached_property
    def edge_ends(self) -> tuple[IntArray, IntArray]:
        """Both ends of every edge, once each way, row by row (the adjacency's order)."""
        rows = np.repeat(np.arange(len(self), dtype=np.int64), np.diff(self.neighbour_start))
        return rows, self.neighbour_index

    @cached_property
    def topological_order(self) -> IntArray:
        """Indices sorted by layer (supports always come before the tiles they carry)."""
        return np.argsort(self.layer, kind="stable")

    @cached_property
    def total_work(self) -> float:
        return float(self.cost.sum())


def _touching_pairs(structure: Structure, ids: list[int], support_lists: tuple[tuple[int, ...], ...]) -> IntArray:
    """(i, j) index pairs, i < j, sorted, of the tiles that touch or rest on one another."""
    n = len(ids)
    id_array = np.array(ids, dtype=np.int64)
    by_id = np.argsort(id_array)
    # from an iterator: numpy reads 76k little tuples one by one three times faster so
    flat = chain.from_iterable(structure.contacts)
    contacts = np.fromiter(flat, dtype=np.int64, count=2 * len(structure.contacts)).reshape(-1, 2)
    a, b = by_id[np.searchsorted(id_array[by_id], contacts)].T  # indices of the contacts' ids
    a, b = np.minimum(a, b), np.maximum(a, b)
    upper = np.repeat(np.arange(n, dtype=np.int64), [len(below) for below in support_lists])
    lower = np.fromiter((s for below in support_lists for s in below), dtype=np.int64, count=len(upper))
    first = np.concatenate([a, np.minimum(upper, lower)])
    second = np.concatenate([b, np.maximum(upper, lower)])
    keys = np.sort(first * max(n, 1) + second)
    keys = keys[np.concatenate([keys[:1] == keys[:1], keys[1:] != keys[:-1]])]  # each pair once, as np.unique
    return np.column_stack([keys // max(n, 1), keys % max(n, 1)]).reshape(-1, 2)


def connected_components(start: IntArray, neighbours: IntArray) -> tuple[int, IntArray]:
    """Connected pieces of an undirected graph in compressed sparse rows (both directions of
    every edge): their number and each node's piece, numbered as scipy.sparse.csgraph numbers them
    (in the order of each piece's lowest node), without importing scipy.

    Union by hooking, as arrays: every node points to a node of its piece with a lower index (at
    first itself), pointers are followed to the end (pointer jumping), then wherever an edge joins
    two such ends, the higher end is pointed at the lowest end it meets. Every end either hooks or
    is hooked onto, so their number at least halves each round; the lowest node of a piece never
    hooks, and ends as the piece's only end.
    """
    n = len(start) - 1
    rows = np.repeat(np.arange(n, dtype=np.int64), np.diff(start))
    label = np.arange(n, dtype=np.int64)
    while True:
        ends_a, ends_b = label[rows], label[neighbours]
        apart = ends_a != ends_b
        if not apart.any():
            break
        higher, lower = np.maximum(ends_a[apart], ends_b[apart]), np.minimum(ends_a[apart], ends_b[apart])
        np.minimum.at(label, higher, lower)
        while True:  # follow the pointers to their ends
            jumped = label[label]
            if np.array_equal(jumped, label):
                break
            label = jumped
    roots, piece = np.unique(label, return_inverse=True)
    return len(roots), piece.astype(np.int64)


def _dependent_lists(support_lists: tuple[tuple[int, ...], ...], ids: list[int]) -> tuple[tuple[int, ...], ...]:
    """The indices resting on each tile in increasing order of their ids: `Structure.supported_by`
    by index, without its dictionaries."""
    dependents: list[list[int]] = [[] for _ in support_lists]
    for upper, below in enumerate(support_lists):
        for lower in below:
            dependents[lower].append(upper)  # increasing indices: increasing ids when ids increase
    if any(a > b for a, b in pairwise(ids)):
        dependents = [sorted(d, key=ids.__getitem__) for d in dependents]
    return tuple(tuple(d) for d in dependents)


def _layers(support_lists: tuple[tuple[int, ...], ...], dependent_lists: tuple[tuple[int, ...], ...]) -> list[int]:
    """`Structure.layers` by index: 0 without supports, else one above the highest support.

    Every tile is reached once all its supports are (the supports form no cycle in a Structure)."""
    waiting = [len(below) for below in support_lists]
    layer = [0] * len(support_lists)
    reached = [k for k, count in enumerate(waiting) if count == 0]
    for k in reached:  # the list grows as tiles are reached
        above = layer[k] + 1
        for d in dependent_lists[k]:
            if above > layer[d]:
                layer[d] = above
            waiting[d] -= 1
            if waiting[d] == 0:
                reached.append(d)
    return layer


def build_graph(structure: Structure, time_model: TimeModel) -> AssemblyGraph:
    """The assembly graph of `structure` with tile costs under `time_model`, for robots starting at
    their caches (`replace` its `first_trip` with `TimeModel.start_trips` for robots elsewhere)."""
    ids = list(structure.tiles)
    n = len(ids)
    index = {t: k for k, t in enumerate(ids)}
    tiles = [structure.tiles[t] for t in ids]
    centroids = np.array([t.centroid for t in tiles], dtype=float).reshape(n, 3)
    to_tile, to_cache = time_model.trips(structure)
    travel = np.array([to_tile[t] for t in ids], dtype=float)
    back = np.array([to_cache[t] for t in ids], dtype=float)
    # TimeModel.tile_cost, without working out the trips a second time
    cost = np.array([time_model.handling_time(t.type_name) for t in tiles], dtype=float).reshape(n) + travel + back
    place = np.array([time_model.place_duration(t.type_name) for t in tiles], dtype=float)
    pick = np.full(n, time_model.pick_duration(), dtype=float)

    support_lists = tuple(tuple(index[s] for s in structure.supports[t]) for t in ids)
    dependent_lists = _dependent_lists(support_lists, ids)

    edges = _touching_pairs(structure, ids, support_lists)
    weights = np.linalg.norm(centroids[edges[:, 0]] - centroids[edges[:, 1]], axis=1)
    weights = np.maximum(weights, MIN_EDGE_WEIGHT)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    columns = np.concatenate([edges[:, 1], edges[:, 0]])
    by_row = np.lexsort((columns, rows))
    start = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))]).astype(np.int64)
    neighbours, distances = columns[by_row], np.concatenate([weights, weights])[by_row]
    n_components, component = connected_components(start, neighbours)

    return AssemblyGraph(
        tile_ids=np.array(ids, dtype=np.int64),
        type_names=tuple(t.type_name for t in tiles),
        centroids=centroids,
        pick=pick,
        travel=travel,
        back=back,
        place=place,
        cost=cost,
        neighbour_start=start,
        neighbour_index=neighbours,
        neighbour_distance=distances,
        support_lists=support_lists,
        dependent_lists=dependent_lists,
        layer=np.array(_layers(support_lists, dependent_lists), dtype=np.int64),
        component=component,
        n_components=int(n_components),
        first_trip=np.zeros((0, n)),
    )
