"""Layer-balanced partition: the default method's starting split (beyond paper section 2.1).

The paper's multi-source Dijkstra grows regions through the contact graph; in a running-bond wall
or a pyramid those regions come out as wedges and bands (a robot owning only upper courses waits
for its neighbours all along), so a plan can be perfectly balanced and still finish late. Here
every robot gets a slice of every layer instead: within each piece of the structure the tiles are
ordered around it (by angle about its centre, the first slice centred on the left, for a compact
footprint; along its long axis for an elongated one), and each layer is cut, in that order, into
consecutive runs of equal work. The cuts carry over each layer's rounding to the next, so that
totals stay balanced. Stacked slices form a vertical sector or strip per robot, every robot builds
at the same pace from the ground up, and a robot waits only at the edges of its strip.

A slice that does not touch the rest of its robot's region (a layer with gaps) is handed to the
neighbouring region it touches with the least work, so that every region ends up connected.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph, connected_components
from planner_node.initial_allocation import split_among_pieces

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

ELONGATED = 0.5  # spread across / spread along below which a footprint is cut in strips
REPAIR_ROUNDS = 8


def slice_order(graph: AssemblyGraph, members: IntArray, robots: int) -> FloatArray:
    """A key per member tile: position around (or along) its piece, left first."""
    xy = graph.centroids[members, :2]
    centre = xy.mean(axis=0)
    if len(members) < 3:
        return xy[:, 0] - centre[0]
    _, spread, axes = np.linalg.svd(xy - centre, full_matrices=False)
    if spread[0] <= 0 or spread[1] < ELONGATED * spread[0]:
        major = axes[0] if axes[0][0] >= 0 else -axes[0]
        return (xy - centre) @ major
    angle = np.arctan2(xy[:, 1] - centre[1], xy[:, 0] - centre[0])
    # 0 at the start of the first slice, which is centred on the left (-x); counter-clockwise
    return np.mod(angle - math.pi + math.pi / robots, 2 * math.pi)


def _cut_layers(graph: AssemblyGraph, members: IntArray, robots: list[int]) -> IntArray:
    k = len(robots)
    owner = np.full(len(members), robots[0], dtype=np.int64)
    if k == 1:
        return owner
    key = slice_order(graph, members, k)
    layer = graph.layer[members]
    cost = graph.cost[members]
    loads = np.zeros(k)
    done = 0.0
    for level in np.unique(layer):
        here = np.flatnonzero(layer == level)
        here = here[np.argsort(key[here], kind="stable")]
        c = cost[here]
        done += c.sum()
        target = np.clip(done / k - loads, 0.0, None)
        if target.sum() <= 0:
            target = np.ones(k)
        bounds = np.cumsum(target) / target.sum() * c.sum()
        slot = np.minimum(np.searchsorted(bounds, np.cumsum(c) - c / 2, side="right"), k - 1)
        loads += np.bincount(slot, weights=c, minlength=k)
        owner[here] = np.asarray(robots)[slot]
    return owner


def _repair_connectivity(graph: AssemblyGraph, owner: IntArray, n_robots: int) -> IntArray:
    """Hand every detached fragment of a region to the lightest region it touches."""
    owner = owner.copy()
    rows, cols = graph.edge_ends
    n = len(graph)
    for _ in range(REPAIR_ROUNDS):
        same = owner[rows] == owner[cols]
        # the edges within regions, still row by row
        inner_start = np.concatenate([[0], np.cumsum(np.bincount(rows[same], minlength=n))]).astype(np.int64)
        count, label = connected_components(inner_start, cols[same])
        work = np.bincount(label, weights=graph.cost, minlength=count)
        region_of = np.zeros(count, dtype=np.int64)
        region_of[label] = owner
        # the main part of a region is its heaviest fragment
        by_work = np.lexsort((-work, region_of))
        first = np.ones(count, dtype=bool)
        first[1:] = region_of[by_work[1:]] != region_of[by_work[:-1]]
        detached = np.ones(count, dtype=bool)
        detached[by_work[first]] = False
        if not detached.any():
            break
        cross = ~same & detached[label[rows]]
        # attach to the main part of a neighbour where possible, so that fragments never swap
        onto_main = cross & ~detached[label[cols]]
        if onto_main.any():
            cross = onto_main
        pairs = np.unique(np.column_stack([label[rows[cross]], owner[cols[cross]]]), axis=0)
        loads = np.bincount(owner, weights=graph.cost, minlength=n_robots)
        touching: dict[int, list[int]] = {}
        for frag, other in pairs.tolist():
            touching.setdefault(frag, []).append(other)
        if not touching:
            break  # only separate pieces of the structure are left: nothing to attach them to
        # heaviest fragments first, each to the region lightest at that moment, so that fragments
        # handed out in one round do not all pile onto the same light region
        taker: dict[int, int] = {}
        for frag in sorted(touching, key=lambda f: (-work[f], f)):
            other = min(touching[frag], key=lambda r: (loads[r], r))
            taker[frag] = other
            loads[other] += work[frag]
            loads[region_of[frag]] -= work[frag]
        region_map = region_of.copy()
        for frag, other in taker.items():
            region_map[frag] = other
        owner = region_map[label]
    return owner


def layer_partition(graph: AssemblyGraph, n_robots: int) -> IntArray:
    """Owner (robot index) of every tile; see the module docstring."""
    owner = np.zeros(len(graph), dtype=np.int64)
    for members, robots in split_among_pieces(graph, n_robots):
        owner[members] = _cut_layers(graph, members, robots)
    return _repair_connectivity(graph, owner, n_robots)
