"""Plane geometry of a structure's footprint for choosing the starting tiles (paper section 2.1:
"starting nodes ... equally spaced along the exterior"): its convex hull and how far apart its
tiles stand.

Written here rather than taken from scipy.spatial (Qhull, k-d trees): importing scipy.spatial
costs about a quarter of a second, an eighth of the `plan` command's budget for 10,000 tiles, and
these two questions about a few thousand points in the plane need neither.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

COLLINEAR = 1e-12  # m^2: a turn with a smaller cross product is no corner of the hull
CROWDED = 64  # points in one cell beyond which the cells are made smaller
MAX_HALVINGS = 30  # of the cell size (identical points stay in one cell however small)


def _turns_left(points: list[tuple[float, float]], o: int, a: int, b: int) -> bool:
    (ox, oy), (ax, ay), (bx, by) = points[o], points[a], points[b]
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox) > COLLINEAR


def convex_hull_indices(points: FloatArray) -> IntArray | None:
    """Indices of the corners of the convex hull of 2-D `points`, counter-clockwise from the
    leftmost (lowest first), points on its edges left out; None when the points lie on one line
    (no hull with an inside), as Qhull refuses them too. Monotone chain (Andrew's algorithm)."""
    order = np.lexsort((points[:, 1], points[:, 0])).tolist()
    xy = [(x, y) for x, y in points[:, :2].tolist()]  # Python floats: the same arithmetic, faster
    lower: list[int] = []
    for k in order:
        while len(lower) >= 2 and not _turns_left(xy, lower[-2], lower[-1], k):
            lower.pop()
        lower.append(k)
    upper: list[int] = []
    for k in reversed(order):
        while len(upper) >= 2 and not _turns_left(xy, upper[-2], upper[-1], k):
            upper.pop()
        upper.append(k)
    corners = lower[:-1] + upper[:-1]
    return np.array(corners, dtype=np.int64) if len(corners) >= 3 else None


def nearest_neighbour_distances(points: FloatArray) -> FloatArray:
    """For each of the 2-D `points` (at least two), the distance to the nearest other point.

    Spatial hashing: with square cells of side `cell`, a point's nearest neighbour, when it is at
    most `cell` away, lies in the 3 x 3 cells around the point's own; the few points left without
    one so near are compared with every point. The cells hold about four points each where the
    points fill a square (a grid's spacing is a little more than side / sqrt(count)).
    """
    count = len(points)
    cell = max(2.0 * float(np.ptp(points, axis=0).max()) / np.sqrt(count), 1e-9)
    keys, width = _cell_keys(points, cell)
    for _ in range(MAX_HALVINGS):  # crowded cells (points bunched far from an outlier): smaller cells
        if np.unique(keys, return_counts=True)[1].max() <= CROWDED:
            break
        cell /= 2
        keys, width = _cell_keys(points, cell)
    by_key = np.argsort(keys, kind="stable")
    sorted_keys = keys[by_key]
    nearest = np.full(count, np.inf)
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            wanted = keys + dx * width + dy
            first = np.searchsorted(sorted_keys, wanted, side="left")
            last = np.searchsorted(sorted_keys, wanted, side="right")
            sizes = last - first
            point = np.repeat(np.arange(count), sizes)
            offsets = np.arange(len(point)) - np.repeat(np.cumsum(sizes) - sizes, sizes)
            other = by_key[np.repeat(first, sizes) + offsets]
            apart = point != other
            point, other = point[apart], other[apart]
            np.minimum.at(nearest, point, _distances(points[point], points[other]))
    for k in np.flatnonzero(nearest > cell).tolist():
        others = np.delete(np.arange(count), k)
        nearest[k] = _distances(points[others], points[k][None, :]).min()
    return nearest


def _cell_keys(points: FloatArray, cell: float) -> tuple[IntArray, int]:
    """Each point's cell as one integer, and the number of keys per column of cells (cells one
    column or row apart differ by `width` or 1)."""
    cells = np.floor((points - points.min(axis=0)) / cell).astype(np.int64)
    width = int(cells[:, 1].max()) + 3  # one spare row each side: keys of neighbours stay distinct
    return (cells[:, 0] + 1) * width + cells[:, 1] + 1, width


def _distances(a: FloatArray, b: FloatArray) -> FloatArray:
    """Euclidean distances row by row, summed as a k-d tree sums them (x first, then y)."""
    dx, dy = a[:, 0] - b[:, 0], a[:, 1] - b[:, 1]
    return np.sqrt(dx * dx + dy * dy)
