"""The assembly graph of paper section 2.1 (after its reference [11], Worcester, Rogoff and Hsieh).

Tiles are the nodes; an undirected edge joins two tiles that touch, side by side or stacked
(`Structure.contacts`, plus every support pair), weighted by the distance between their centroids.
The precedence DAG is the support relation: a tile's supports must be placed before it. Every
tile also carries its cost phases under the time model: pick at its type's cache, carry to the
structure, place, return to the cache (`TimeModel.tile_cost` is their sum).

The planner works on array indices 0..n-1 (tiles in increasing id order); `tile_ids` maps back.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components

from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel

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
    travel: FloatArray  # (n,) s, one way between the cache and the tile
    place: FloatArray  # (n,) s, placing it
    cost: FloatArray  # (n,) s, TimeModel.tile_cost: pick + 2 travel + place
    adjacency: csr_matrix  # (n, n) symmetric, centroid distances of touching tiles
    support_lists: tuple[tuple[int, ...], ...]  # indices each tile rests on
    dependent_lists: tuple[tuple[int, ...], ...]  # indices resting on each tile
    layer: IntArray  # (n,) 0 on the floor, else one above the highest support
    component: IntArray  # (n,) connected component of the contact graph
    n_components: int

    def __len__(self) -> int:
        return len(self.tile_ids)

    @cached_property
    def index_of(self) -> dict[int, int]:
        return {int(t): k for k, t in enumerate(self.tile_ids)}

    @cached_property
    def neighbor_lists(self) -> tuple[tuple[int, ...], ...]:
        """Touching tiles of each tile (Python tuples: the trading loop indexes them one by one)."""
        ptr, idx = self.adjacency.indptr, self.adjacency.indices.tolist()
        return tuple(tuple(idx[ptr[k] : ptr[k + 1]]) for k in range(len(self)))

    @cached_property
    def topological_order(self) -> IntArray:
        """Indices sorted by layer (supports always come before the tiles they carry)."""
        return np.argsort(self.layer, kind="stable")

    @cached_property
    def total_work(self) -> float:
        return float(self.cost.sum())


def build_graph(structure: Structure, time_model: TimeModel) -> AssemblyGraph:
    """The assembly graph of `structure` with tile costs under `time_model`."""
    ids = list(structure.tiles)
    n = len(ids)
    index = {t: k for k, t in enumerate(ids)}
    tiles = [structure.tiles[t] for t in ids]
    centroids = np.array([t.centroid for t in tiles], dtype=float).reshape(n, 3)
    travel = np.array([time_model.travel_time(structure, t) for t in ids], dtype=float)
    cost = np.array([time_model.tile_cost(structure, t) for t in ids], dtype=float)
    place = np.array([time_model.place_duration(t.type_name) for t in tiles], dtype=float)
    pick = np.full(n, time_model.pick_time, dtype=float)

    support_lists = tuple(tuple(index[s] for s in structure.supports[t]) for t in ids)
    dependent_lists = tuple(tuple(index[d] for d in structure.supported_by[t]) for t in ids)

    pairs = {(index[a], index[b]) for a, b in structure.contacts}
    pairs.update((min(i, s), max(i, s)) for i, below in enumerate(support_lists) for s in below)
    if pairs:
        edges = np.array(sorted(pairs), dtype=np.int64)
        weights = np.linalg.norm(centroids[edges[:, 0]] - centroids[edges[:, 1]], axis=1)
        weights = np.maximum(weights, MIN_EDGE_WEIGHT)
        rows = np.concatenate([edges[:, 0], edges[:, 1]])
        cols = np.concatenate([edges[:, 1], edges[:, 0]])
        adjacency = coo_matrix((np.concatenate([weights, weights]), (rows, cols)), shape=(n, n)).tocsr()
    else:
        adjacency = csr_matrix((n, n), dtype=float)
    adjacency.sort_indices()
    n_components, component = connected_components(adjacency, directed=False)

    layers = structure.layers
    return AssemblyGraph(
        tile_ids=np.array(ids, dtype=np.int64),
        type_names=tuple(t.type_name for t in tiles),
        centroids=centroids,
        pick=pick,
        travel=travel,
        place=place,
        cost=cost,
        adjacency=adjacency,
        support_lists=support_lists,
        dependent_lists=dependent_lists,
        layer=np.array([layers[t] for t in ids], dtype=np.int64),
        component=component.astype(np.int64),
        n_components=int(n_components),
    )
