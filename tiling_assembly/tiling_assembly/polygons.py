"""Planar polygon geometry for tile footprints and faces (paper section 2: tiles are polytopes).

Small, exact-enough routines on 2-D polygons given as (N, 2) arrays: orientation, simplicity,
convexity, ear-clipping triangulation and the overlap area of two polygons. Tolerances are in
metres (or square metres) because every caller works in the map frame.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

Polygon = NDArray[np.float64]  # (N, 2) corners, in order, not repeated at the end

EPS = 1e-12


def signed_area(polygon: Polygon) -> float:
    """Shoelace area: positive when the corners run counter-clockwise."""
    x, y = polygon[:, 0], polygon[:, 1]
    return 0.5 * float(x[:-1] @ y[1:] - y[:-1] @ x[1:] + x[-1] * y[0] - y[-1] * x[0])


def _cross(o: NDArray[np.float64], a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def _segments_intersect(p1, p2, q1, q2) -> bool:  # type: ignore[no-untyped-def]
    """Whether closed segments p1p2 and q1q2 share a point (collinear overlaps included)."""
    d1, d2 = _cross(q1, q2, p1), _cross(q1, q2, p2)
    d3, d4 = _cross(p1, p2, q1), _cross(p1, p2, q2)
    if ((d1 > EPS and d2 < -EPS) or (d1 < -EPS and d2 > EPS)) and (
        (d3 > EPS and d4 < -EPS) or (d3 < -EPS and d4 > EPS)
    ):
        return True

    def on_segment(a, b, c) -> bool:  # type: ignore[no-untyped-def]
        return (
            abs(_cross(a, b, c)) <= EPS
            and min(a[0], b[0]) - EPS <= c[0] <= max(a[0], b[0]) + EPS
            and min(a[1], b[1]) - EPS <= c[1] <= max(a[1], b[1]) + EPS
        )

    return (
        on_segment(q1, q2, p1)
        or on_segment(q1, q2, p2)
        or on_segment(p1, p2, q1)
        or on_segment(p1, p2, q2)
    )


def simplicity_problem(polygon: Polygon, min_area: float = 1e-8) -> str | None:
    """Why `polygon` is not a simple polygon, or None when it is.

    Simple means: at least three corners, no repeated corner, non-zero area and no two edges that
    meet anywhere but at the corner they share.
    """
    n = len(polygon)
    if n < 3:
        return f"a polygon needs at least 3 corners, got {n}"
    for i in range(n):
        for j in range(i + 1, n):
            if np.allclose(polygon[i], polygon[j], atol=1e-9):
                return f"corners {i} and {j} coincide"
    for i in range(n):
        a1, a2 = polygon[i], polygon[(i + 1) % n]
        for j in range(i + 1, n):
            if j == i or (j + 1) % n == i or j == (i + 1) % n:
                continue  # neighbouring edges share a corner by construction
            b1, b2 = polygon[j], polygon[(j + 1) % n]
            if _segments_intersect(a1, a2, b1, b2):
                return f"edges {i}-{(i + 1) % n} and {j}-{(j + 1) % n} cross"
    # neighbouring edges that fold back onto each other also make the polygon non-simple
    for i in range(n):
        prev, here, nxt = polygon[i - 1], polygon[i], polygon[(i + 1) % n]
        if abs(_cross(prev, here, nxt)) <= EPS and np.dot(here - prev, nxt - here) < 0:
            return f"the polygon folds back on itself at corner {i}"
    if abs(signed_area(polygon)) < min_area:
        return "the polygon has (almost) zero area"
    return None


def counter_clockwise(polygon: Polygon) -> Polygon:
    """The same polygon with its corners counter-clockwise."""
    return polygon if signed_area(polygon) > 0 else polygon[::-1].copy()


def is_convex(polygon: Polygon) -> bool:
    """Whether a simple counter-clockwise polygon is convex (collinear corners allowed)."""
    n = len(polygon)
    return all(
        _cross(polygon[i - 1], polygon[i], polygon[(i + 1) % n]) >= -EPS for i in range(n)
    )


def triangulate(polygon: Polygon) -> list[tuple[int, int, int]]:
    """Ear-clipping triangulation of a simple polygon (corner indices, each triangle counter-clockwise).

    Clockwise corners are walked in reverse: every corner of a clockwise polygon would otherwise look
    reflex, and no ear would be found.
    """
    remaining = list(range(len(polygon)))
    if signed_area(polygon) < 0:
        remaining.reverse()
    triangles: list[tuple[int, int, int]] = []
    guard = 0
    while len(remaining) > 3 and guard < 10 * len(polygon) ** 2:
        guard += 1
        m = len(remaining)
        for k in range(m):
            ia, ib, ic = remaining[k - 1], remaining[k], remaining[(k + 1) % m]
            a, b, c = polygon[ia], polygon[ib], polygon[ic]
            if _cross(a, b, c) <= EPS:
                continue  # reflex or flat corner: not an ear
            if any(
                _point_in_triangle(polygon[j], a, b, c)
                for j in remaining
                if j not in (ia, ib, ic)
            ):
                continue
            triangles.append((ia, ib, ic))
            remaining.pop(k)
            break
        else:
            # only flat corners are left: drop one so the loop can finish
            remaining.pop(0)
    if len(remaining) == 3:
        a, b, c = (polygon[i] for i in remaining)
        if abs(_cross(a, b, c)) > EPS:
            triangles.append((remaining[0], remaining[1], remaining[2]))
    return triangles


def _point_in_triangle(p, a, b, c) -> bool:  # type: ignore[no-untyped-def]
    return _cross(a, b, p) >= -EPS and _cross(b, c, p) >= -EPS and _cross(c, a, p) >= -EPS


def clip_convex(subject: Polygon, clip: Polygon) -> Polygon:
    """Sutherland-Hodgman: the part of `subject` inside the convex counter-clockwise `clip`."""
    output = subject
    n = len(clip)
    for i in range(n):
        if len(output) == 0:
            break
        a, b = clip[i], clip[(i + 1) % n]
        edge = b - a
        side = edge[0] * (output[:, 1] - a[1]) - edge[1] * (output[:, 0] - a[0])
        kept: list[NDArray[np.float64]] = []
        m = len(output)
        for j in range(m):
            cur, nxt = output[j], output[(j + 1) % m]
            s_cur, s_nxt = side[j], side[(j + 1) % m]
            if s_cur >= 0:
                kept.append(cur)
            if (s_cur >= 0) != (s_nxt >= 0):
                t = s_cur / (s_cur - s_nxt)
                kept.append(cur + t * (nxt - cur))
        output = np.array(kept) if kept else np.zeros((0, 2))
    return output


def convex_overlap_area(a: Polygon, b: Polygon) -> float:
    """Area shared by two convex counter-clockwise polygons."""
    shared = clip_convex(a, b)
    return abs(signed_area(shared)) if len(shared) >= 3 else 0.0


def convex_hull_2d(points: NDArray[np.float64]) -> Polygon:
    """Counter-clockwise convex hull of 2-D points (monotone chain), collinear points dropped."""
    pts = np.unique(np.round(points, 12), axis=0)
    if len(pts) < 3:
        return pts
    order = np.lexsort((pts[:, 1], pts[:, 0]))
    pts = pts[order]
    lower: list[NDArray[np.float64]] = []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= EPS:
            lower.pop()
        lower.append(p)
    upper: list[NDArray[np.float64]] = []
    for p in pts[::-1]:
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= EPS:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def point_in_polygon(point: NDArray[np.float64], polygon: Polygon, tolerance: float) -> bool:
    """Whether `point` lies inside `polygon` or within `tolerance` of its boundary."""
    n = len(polygon)
    for i in range(n):
        a, b = polygon[i], polygon[(i + 1) % n]
        ab = b - a
        t = np.clip(np.dot(point - a, ab) / max(np.dot(ab, ab), EPS), 0.0, 1.0)
        if np.linalg.norm(point - (a + t * ab)) <= tolerance:
            return True
    inside = False
    x, y = point
    for i in range(n):
        (x1, y1), (x2, y2) = polygon[i], polygon[(i + 1) % n]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside
