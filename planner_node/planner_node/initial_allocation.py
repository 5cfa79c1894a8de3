"""Initial allocation: multi-source Dijkstra from seeds spread along the exterior (paper section 2.1).

"The approach uses Dijkstra's algorithm with multiple starting nodes to generate a set of assembly
tasks for each robot. ... each robot's task is composed of tiles that are closest to the starting
node. The starting nodes are chosen to be equally spaced along the exterior."

Starting tiles are ground-layer tiles on the exterior of the footprint: those whose centres lie on
(or within half a tile spacing of) the convex hull of the ground tiles' centres, picked at equal
arc length around the hull, counter-clockwise from the leftmost (-x) side, so that robot 1 starts
on the left. A footprint thinner than the spacing between seeds (a wall: its hull's two long
sides are the same tiles) is treated as a line instead: seeds at equal steps along its long axis.
One Dijkstra from all seeds at once (scipy.sparse.csgraph) then gives every tile to the robot whose
seed is nearest through the contact graph; every region is a shortest-path tree, hence connected.

A structure in several separate pieces gets seeds per piece in proportion to the piece's work;
pieces too light for a robot of their own are dealt whole to the least loaded robot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import ConvexHull, QhullError, cKDTree

from planner_node.assembly_graph import AssemblyGraph

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

NO_ROBOT = -1


@dataclass(frozen=True, eq=False)
class InitialAllocation:
    owner: IntArray  # (n,) robot index of every tile
    seeds: tuple[int, ...]  # seed tile index of every robot (NO_ROBOT for a robot without tiles)
    distance: FloatArray  # (n,) m, graph distance from the tile to its region's seed
    seed_distance: FloatArray  # (robots, n) m, graph distance from each robot's seed(s) to each tile


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
    try:
        hull = xy[ConvexHull(xy).vertices]  # counter-clockwise
        _, _, perimeter = _arc_positions(xy[:1], hull)
    except (QhullError, ValueError):
        hull, perimeter = None, 0.0

    spacing, _ = cKDTree(xy).query(xy, k=2)
    tolerance = max(0.5 * float(np.median(spacing[:, 1])), 1e-6)
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
    if n == 0:
        empty = np.zeros(0)
        return InitialAllocation(np.zeros(0, dtype=np.int64), tuple([NO_ROBOT] * n_robots), empty,
                                 np.zeros((n_robots, 0)))
    seeds: list[int] = []
    seed_robot: list[int] = []
    for members, robots in split_among_pieces(graph, n_robots):
        chosen = exterior_seeds(graph, members, len(robots))
        seeds += chosen
        seed_robot += robots[: len(chosen)]
    from_seed = np.atleast_2d(dijkstra(graph.adjacency, directed=True, indices=seeds))
    seed_distance = np.full((n_robots, n), np.inf)
    for row, r in zip(from_seed, seed_robot, strict=True):
        np.minimum(seed_distance[r], row, out=seed_distance[r])
    # owners from the shortest-path forest, so that every region is a tree (connected) even
    # where two seeds are exactly as far
    _, _, sources = dijkstra(
        graph.adjacency, directed=True, indices=seeds, return_predecessors=True, min_only=True
    )
    robot_of_seed = np.full(n, NO_ROBOT, dtype=np.int64)
    robot_of_seed[seeds] = seed_robot
    owner = robot_of_seed[sources]
    robot_seed = [NO_ROBOT] * n_robots
    for s, r in zip(seeds, seed_robot, strict=True):
        if robot_seed[r] == NO_ROBOT:
            robot_seed[r] = s
    distance = seed_distance[owner, np.arange(n)]
    return InitialAllocation(owner, tuple(robot_seed), distance, seed_distance)
