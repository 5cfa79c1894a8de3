"""Initial allocation: multi-source Dijkstra from seeds spread along the exterior (paper section 2.1).

"The approach uses Dijkstra's algorithm with multiple starting nodes to generate a set of assembly
tasks for each robot. ... each robot's task is composed of tiles that are closest to the starting
node. The starting nodes are chosen to be equally spaced along the exterior."

Starting tiles are ground-layer tiles on the exterior of the footprint: those whose centres lie on
(or within half a tile spacing of) the convex hull of the ground tiles' centres, picked at equal
arc length around the hull, counter-clockwise from the leftmost (-x) side, so that robot 1 starts
on the left. A footprint thinner than the spacing between seeds (a wall: its hull's two long
sides are the same tiles) is treated as a line instead: seeds at equal steps along its long axis.
One Dijkstra from all seeds at once then gives every tile to the robot whose seed is nearest
through the contact graph; every region is a shortest-path tree, hence connected.

A structure in several separate pieces gets seeds per piece in proportion to the piece's work;
pieces too light for a robot of their own are dealt whole to the least loaded robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from heapq import heapify, heappop, heappush

import numpy as np
from numpy.typing import NDArray

from planner_node.assembly_graph import AssemblyGraph
from planner_node.footprint import convex_hull_indices, nearest_neighbour_distances

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

NO_ROBOT = -1


@dataclass(frozen=True, eq=False)
class InitialAllocation:
    """The seeds and the regions around them.

    `distance` is worked out at once. The regions (`owner`) and every robot's distances
    (`seed_distance`) are worked out when first asked for, by scipy's Dijkstra: importing it costs
    the `plan` command a third of a second, and the default method on big structures uses neither.
    """

    graph: AssemblyGraph
    n_robots: int
    seeds: tuple[int, ...]  # seed tile index of every robot (NO_ROBOT for a robot without tiles)
    seed_tiles: tuple[int, ...]  # every seed (a robot may have one in each of several pieces)
    seed_robots: tuple[int, ...]  # the robot of each of `seed_tiles`
    # (n,) m, graph distance from the tile to its region's seed: the nearest seed, since every
    # region is a shortest-path tree around its seed
    distance: FloatArray

    @cached_property
    def seed_distance(self) -> FloatArray:
        """(robots, n) m, graph distance from each robot's seed(s) to each tile."""
        seed_distance = np.full((self.n_robots, len(self.graph)), np.inf)
        if not self.seed_tiles:
            return seed_distance
        from scipy.sparse.csgraph import dijkstra

        from_seed = np.atleast_2d(dijkstra(self.graph.adjacency, directed=True, indices=list(self.seed_tiles)))
        for row, r in zip(from_seed, self.seed_robots, strict=True):
            np.minimum(seed_distance[r], row, out=seed_distance[r])
        return seed_distance

    @cached_property
    def owner(self) -> IntArray:
        """(n,) robot index of every tile, from the shortest-path forest of all seeds, so that every
        region is a tree (connected) even where two seeds are exactly as far."""
        n = len(self.graph)
        if not self.seed_tiles:
            return np.zeros(n, dtype=np.int64)
        from scipy.sparse.csgraph import dijkstra

        _, _, sources = dijkstra(
            self.graph.adjacency, directed=True, indices=list(self.seed_tiles), return_predecessors=True,
            min_only=True,
        )
        robot_of_seed = np.full(n, NO_ROBOT, dtype=np.int64)
        robot_of_seed[list(self.seed_tiles)] = self.seed_robots
        return robot_of_seed[sources]


def nearest_seed_distances(graph: AssemblyGraph, seeds: list[int]) -> FloatArray:
    """Graph distance from every tile to the nearest of `seeds` (m): one Dijkstra from all seeds.

    The same numbers as scipy's: with positive weights, every correct Dijkstra finds the one
    solution of d(v) = min over neighbours u of (d(u) + w(u, v)) in floating point.
    """
    start = graph.neighbour_start.tolist()
    neighbours = graph.neighbour_index.tolist()
    weights = graph.neighbour_distance.tolist()
    distance = [math.inf] * len(graph)
    heap: list[tuple[float, int]] = []
    for s in seeds:
        distance[s] = 0.0
        heap.append((0.0, s))
    heapify(heap)
    while heap:
        d, u = heappop(heap)
        if d > distance[u]:
            continue  # reached sooner by another path
        first, last = start[u], start[u + 1]
        for v, weight in zip(neighbours[first:last], weights[first:last], strict=True):
            through_u = d + weight
            if through_u < distance[v]:
                distance[v] = through_u
                heappush(heap, (through_u, v))
    return np.array(distance)


def _farthest_points(points: FloatArray, chosen: list[int], count: int) -> list[int]:
    """Add `count` indices of `points`, each the farthest from those chosen so far."""
    chosen = list(chosen)
    if not chosen:
        chosen.append(int(np.lexsort((points[:, 1], points[:, 0]))[0]))
        count -= 1
    nearest = np.min(np.linalg.norm(points[:, None, :] - points[None, chosen, :], axis=2), axis=1)
    for _ in range(count):
        pick = int(np.argmax(nearest))
        chosen.append(pick)
        nearest = np.minimum(nearest, np.linalg.norm(points - points[pick], axis=1))
    return chosen


def _arc_positions(points: FloatArray, hull: FloatArray) -> tuple[FloatArray, FloatArray, float]:
    """Distance of each point to the closed polygon `hull` and its arc parameter along it."""
    a = hull
    b = np.roll(hull, -1, axis=0)
    edge = b - a
    length = np.linalg.norm(edge, axis=1)
    offsets = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    rel = points[:, None, :] - a[None, :, :]
    t = np.clip(np.einsum("mhk,hk->mh", rel, edge) / np.maximum(length**2, 1e-18), 0.0, 1.0)
    closest = a[None, :, :] + t[:, :, None] * edge[None, :, :]
    dist = np.linalg.norm(points[:, None, :] - closest, axis=2)
    nearest = np.argmin(dist, axis=1)
    rows = np.arange(len(points))
    arc = offsets[nearest] + t[rows, nearest] * length[nearest]
    return dist[rows, nearest], arc, float(length.sum())


def exterior_seeds(graph: AssemblyGraph, tiles: IntArray, count: int) -> list[int]:
    """`count` seed tiles among `tiles` (one connected piece), ordered as the robots get them."""
    count = min(count, len(tiles))
    if count <= 0:
        return []
    ground = tiles[graph.layer[tiles] == graph.layer[tiles].min()]
    if len(ground) <= count:
        rest = np.setdiff1d(tiles, ground)
        if len(rest) == 0 or len(ground) == count:
            return [int(t) for t in ground[:count]]
        points = graph.centroids[np.concatenate([ground, rest])]
        chosen = _farthest_points(points, list(range(len(ground))), count - len(ground))
        return [int(np.concatenate([ground, rest])[k]) for k in chosen]

    xy = graph.centroids[ground, :2]
    centre = xy.mean(axis=0)
    _, _, axes = np.linalg.svd(xy - centre, full_matrices=False)
    major = axes[0] if axes[0][0] > 1e-12 or (abs(axes[0][0]) <= 1e-12 and axes[0][1] > 0) else -axes[0]
    minor = np.array([-major[1], major[0]])
    along = (xy - centre) @ major
    width = float(np.ptp((xy - centre) @ minor))
    corners = convex_hull_indices(xy)
    hull, perimeter = None, 0.0
    if corners is not None:
        hull = xy[corners]  # counter-clockwise
        _, _, perimeter = _arc_positions(xy[:1], hull)
    tolerance = max(0.5 * float(np.median(nearest_neighbour_distances(xy))), 1e-6)
    if hull is None or width < 0.5 * perimeter / count:
        # a line-like footprint: seeds at equal steps along its long axis, on its exterior
        if hull is not None:
            dist, _, _ = _arc_positions(xy, hull)
            outside = np.flatnonzero(dist <= tolerance)
        else:
            outside = np.arange(len(ground))
        if len(outside) < count:
            outside = np.arange(len(ground))
        low, span = float(along.min()), float(np.ptp(along))
        free = np.ones(len(outside), dtype=bool)
        seeds = []
        for j in range(count):
            gap = np.abs(along[outside] - (low + (j + 0.5) * span / count))
            gap -= 1e-6 * np.abs(along[outside])  # a tie goes to the tile nearer the end
            gap[~free] = np.inf
            k = int(np.argmin(gap))
            free[k] = False
            seeds.append(int(ground[outside[k]]))
        return seeds

    dist, arc, perimeter = _arc_positions(xy, hull)
    outside = np.flatnonzero(dist <= tolerance)
    if len(outside) < count:
        chosen = _farthest_points(xy, outside.tolist(), count - len(outside))
        return [int(ground[k]) for k in chosen]
    angles = np.arctan2(xy[outside, 1] - centre[1], xy[outside, 0] - centre[0])
    start = float(arc[outside][np.argmin(np.abs(np.abs(angles) - math.pi))])
    free = np.ones(len(outside), dtype=bool)
    seeds = []
    for j in range(count):
        target = (start + j * perimeter / count) % perimeter
        gap = np.abs(arc[outside] - target)
        gap = np.minimum(gap, perimeter - gap)
        gap[~free] = np.inf
        k = int(np.argmin(gap))
        free[k] = False
        seeds.append(int(ground[outside[k]]))
    return seeds


def _robots_per_piece(work: FloatArray, sizes: IntArray, n_robots: int) -> IntArray:
    """Robots per piece, one at a time to the piece with the most work per robot (D'Hondt).

    Light pieces may get none: they are dealt whole afterwards.
    """
    count = np.zeros(len(work), dtype=np.int64)
    for _ in range(n_robots):
        per_robot = np.where(count < sizes, work / (count + 1), -np.inf)
        k = int(np.argmax(per_robot))
        if per_robot[k] == -np.inf:
            break
        count[k] += 1
    return count


def split_among_pieces(graph: AssemblyGraph, n_robots: int) -> list[tuple[IntArray, list[int]]]:
    """The structure's separate pieces (left to right) with the robots each one gets.

    Robots go to pieces in proportion to their work and are numbered piece by piece, left to
    right. Pieces too light to get a robot of their own are dealt whole, heaviest first, to the
    robot with the least work so far (that robot then works on two pieces).
    """
    labels = graph.component
    work = np.bincount(labels, weights=graph.cost, minlength=graph.n_components)
    sizes = np.bincount(labels, minlength=graph.n_components)
    left = np.full(graph.n_components, np.inf)
    np.minimum.at(left, labels, graph.centroids[:, 0])
    pieces = np.argsort(left, kind="stable")
    members = {int(c): np.flatnonzero(labels == c) for c in pieces}
    counts = _robots_per_piece(work[pieces], sizes[pieces], n_robots)
    split: list[tuple[IntArray, list[int]]] = []
    load = np.zeros(n_robots)
    first = 0
    for c, k in zip(pieces.tolist(), counts.tolist(), strict=True):
        if k:
            robots = list(range(first, first + k))
            split.append((members[c], robots))
            load[robots] += work[c] / k
            first += k
    unserved = [c for c, k in zip(pieces.tolist(), counts.tolist(), strict=True) if not k]
    for c in sorted(unserved, key=lambda c: (-work[c], left[c])):
        r = int(np.argmin(load))
        load[r] += work[c]
        split.append((members[c], [r]))
    return split


def initial_allocation(graph: AssemblyGraph, n_robots: int) -> InitialAllocation:
    """Split the tiles among `n_robots` robots by multi-source Dijkstra (see the module docstring)."""
    if n_robots < 1:
        raise ValueError("at least one robot is needed")
    n = len(graph)
    seeds: list[int] = []
    seed_robot: list[int] = []
    if n:
        for members, robots in split_among_pieces(graph, n_robots):
            chosen = exterior_seeds(graph, members, len(robots))
            seeds += chosen
            seed_robot += robots[: len(chosen)]
    robot_seed = [NO_ROBOT] * n_robots
    for s, r in zip(seeds, seed_robot, strict=True):
        if robot_seed[r] == NO_ROBOT:
            robot_seed[r] = s
    return InitialAllocation(
        graph=graph,
        n_robots=n_robots,
        seeds=tuple(robot_seed),
        seed_tiles=tuple(seeds),
        seed_robots=tuple(seed_robot),
        distance=nearest_seed_distances(graph, seeds),
    )
