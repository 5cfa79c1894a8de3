"""Tile geometry: shapes in the tile frame and placed tiles in the map frame (paper section 2).

A tile type is a right prism (a simple polygon extruded along +z) or a convex polytope. Its shape
is kept as vertices, planar faces with outward normals (the "planar patches" of paper section
2.2.1), and convex pieces (a non-convex prism is split into triangular prisms) for overlap tests.
A placed tile adds the pose: world vertices, faces, triangles for ray casting, footprint and AABB.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tiling_assembly import polygons

if TYPE_CHECKING:
    from scipy.spatial import ConvexHull

Array = NDArray[np.float64]


class ShapeError(ValueError):
    """A tile type's geometry is not usable; `rule` names the broken rule, the message says why."""

    def __init__(self, rule: str, message: str) -> None:
        super().__init__(message)
        self.rule = rule


def rotation_from_rpy(roll: float, pitch: float, yaw: float) -> Array:
    """Rotation matrix for fixed-axis roll, pitch, yaw (REP 103: R = Rz(yaw) Ry(pitch) Rx(roll))."""
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def rpy_from_rotation(rotation: Array) -> tuple[float, float, float]:
    """Inverse of rotation_from_rpy (pitch in [-pi/2, pi/2])."""
    pitch = float(np.arcsin(np.clip(-rotation[2, 0], -1.0, 1.0)))
    if abs(np.cos(pitch)) > 1e-9:
        roll = float(np.arctan2(rotation[2, 1], rotation[2, 2]))
        yaw = float(np.arctan2(rotation[1, 0], rotation[0, 0]))
    else:  # gimbal lock: put all of the rotation about z into yaw
        roll = 0.0
        yaw = float(np.arctan2(-rotation[0, 1], rotation[1, 1]))
    return roll, pitch, yaw


def quaternion_from_rotation(rotation: Array) -> tuple[float, float, float, float]:
    """Unit quaternion (x, y, z, w) with w >= 0 for a rotation matrix."""
    m = rotation
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4)
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = (s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s)
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s)
    arr = np.array(q, dtype=float)
    arr /= np.linalg.norm(arr)
    if arr[3] < 0:
        arr = -arr
    return float(arr[0]), float(arr[1]), float(arr[2]), float(arr[3])


def rotation_from_quaternion(x: float, y: float, z: float, w: float) -> Array:
    """Rotation matrix of a quaternion (normalised first)."""
    q = np.array([x, y, z, w], dtype=float)
    norm = np.linalg.norm(q)
    if not np.isfinite(norm) or norm < 1e-9:
        raise ValueError("the quaternion is zero or not finite")
    x, y, z, w = q / norm
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


@dataclass(frozen=True)
class Face:
    """A planar face: a loop of vertex indices, counter-clockwise seen from outside."""

    loop: tuple[int, ...]
    normal: Array  # unit, outward


@dataclass(frozen=True, eq=False)
class TileShape:
    """The geometry of a tile type in its own frame."""

    kind: str  # "prism" or "convex"
    vertices: Array  # (V, 3)
    faces: tuple[Face, ...]
    pieces: tuple[tuple[int, ...], ...]  # convex pieces as vertex-index sets (or subsets)
    piece_vertices: tuple[Array, ...]  # the convex pieces' corners, (K, 3) each
    piece_axes: tuple[PieceAxes, ...]  # separating-axis candidates of each piece
    polygon: Array | None = None  # prism only: the counter-clockwise base polygon
    height: float = 0.0  # prism only

    @cached_property
    def triangles(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(T, 3) vertex indices of a triangulation of the surface and (T,) face index each."""
        tris: list[tuple[int, int, int]] = []
        face_of: list[int] = []
        for k, face in enumerate(self.faces):
            for tri in _face_triangles(self.vertices, face):
                tris.append(tri)
                face_of.append(k)
        return np.array(tris, dtype=np.int64), np.array(face_of, dtype=np.int64)

    @cached_property
    def _signed_tetrahedra(self) -> tuple[Array, Array, Array]:
        """Volumes of the tetrahedra from the mean vertex to every surface triangle."""
        tris, _ = self.triangles
        v = self.vertices
        ref = v.mean(axis=0)
        a, b, c = v[tris[:, 0]] - ref, v[tris[:, 1]] - ref, v[tris[:, 2]] - ref
        return np.einsum("ij,ij->i", a, np.cross(b, c)) / 6.0, a + b + c, ref

    @cached_property
    def volume(self) -> float:
        """Volume in cubic metres (the same for every tile of the type)."""
        return float(abs(self._signed_tetrahedra[0].sum()))

    @cached_property
    def centroid(self) -> Array:
        """Centre of volume in the tile frame (computed once per tile type)."""
        vol, corner_sums, ref = self._signed_tetrahedra
        total = vol.sum()
        if abs(total) < 1e-15:
            return ref
        return ref + (corner_sums / 4.0 * vol[:, None]).sum(axis=0) / total


def prism_shape(polygon_points: Array, height: float) -> TileShape:
    """A right prism: `polygon_points` (N, 2) extruded from z = 0 to z = height."""
    problem = polygons.simplicity_problem(polygon_points)
    if problem:
        raise ShapeError("non-simple-polygon", f"the prism polygon is not simple: {problem}")
    if not (np.isfinite(height) and height > 0):
        raise ShapeError("bad-value", f"the prism height must be a positive number of metres, got {height}")
    poly = polygons.counter_clockwise(np.asarray(polygon_points, dtype=float))
    n = len(poly)
    bottom = np.column_stack([poly, np.zeros(n)])
    top = np.column_stack([poly, np.full(n, height)])
    vertices = np.vstack([bottom, top])
    faces = [
        Face(tuple(range(n - 1, -1, -1)), np.array([0.0, 0.0, -1.0])),
        Face(tuple(range(n, 2 * n)), np.array([0.0, 0.0, 1.0])),
    ]
    for i in range(n):
        j = (i + 1) % n
        edge = poly[j] - poly[i]
        normal = np.array([edge[1], -edge[0], 0.0]) / np.linalg.norm(edge)
        faces.append(Face((i, j, n + j, n + i), normal))
    if polygons.is_convex(poly):
        pieces: list[tuple[int, ...]] = [tuple(range(2 * n))]
    else:
        pieces = [(a, b, c, n + a, n + b, n + c) for a, b, c in polygons.triangulate(poly)]
    piece_vertices = tuple(vertices[list(p)] for p in pieces)
    return TileShape(
        kind="prism",
        vertices=vertices,
        faces=tuple(faces),
        pieces=tuple(pieces),
        piece_vertices=piece_vertices,
        piece_axes=tuple(_piece_axes(p, _prism_piece_faces(p)) for p in piece_vertices),
        polygon=poly,
        height=float(height),
    )


def convex_shape(points: Array) -> TileShape:
    """A convex polytope given by its corners; every given point must be a corner of the hull."""
    pts = np.asarray(points, dtype=float)
    if len(pts) < 4:
        raise ShapeError("degenerate-shape", f"a convex polytope needs at least 4 vertices, got {len(pts)}")
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(pts)
    except QhullError:
        raise ShapeError(
            "degenerate-shape", "the vertices are coplanar or degenerate: they enclose no volume"
        ) from None
    if hull.volume < 1e-12:
        raise ShapeError("degenerate-shape", "the vertices enclose no volume")
    not_corners = sorted(set(range(len(pts))) - set(int(i) for i in hull.vertices))
    if not_corners:
        raise ShapeError(
            "non-convex",
            f"vertices {not_corners} are not corners of the convex hull: the input is not convex"
        )
    faces = _hull_faces(pts, hull)
    all_ids = tuple(range(len(pts)))
    return TileShape(
        kind="convex",
        vertices=pts,
        faces=tuple(faces),
        pieces=(all_ids,),
        piece_vertices=(pts,),
        piece_axes=(_piece_axes(pts, faces),),
    )


def _prism_piece_faces(points: Array) -> list[Face]:
    """The faces of a convex prism piece whose first half of `points` is its bottom polygon and the
    second half its top (as `prism_shape` makes them): known without a convex hull, so that loading
    a structure of prisms does not import scipy.spatial (a sixth of a second)."""
    n = len(points) // 2
    ring = list(range(n))
    if polygons.signed_area(points[:n, :2]) < 0:
        ring.reverse()
    faces = [Face(tuple(reversed(ring)), np.array([0.0, 0.0, -1.0])),
             Face(tuple(n + i for i in ring), np.array([0.0, 0.0, 1.0]))]
    for i, j in zip(ring, ring[1:] + ring[:1], strict=True):
        edge = points[j, :2] - points[i, :2]
        faces.append(Face((i, j, n + j, n + i), np.array([edge[1], -edge[0], 0.0]) / np.linalg.norm(edge)))
    return faces


def _hull_faces(points: Array, hull: ConvexHull) -> list[Face]:
    """The hull's faces, coplanar triangles merged into one polygon per plane."""
    groups: dict[tuple[float, ...], set[int]] = {}
    normals: dict[tuple[float, ...], Array] = {}
    for simplex, equation in zip(hull.simplices, hull.equations, strict=True):
        key = tuple(np.round(equation, 7))
        groups.setdefault(key, set()).update(int(i) for i in simplex)
        normals[key] = equation[:3] / np.linalg.norm(equation[:3])
    faces = []
    for key, members in groups.items():
        normal = normals[key]
        ids = np.array(sorted(members))
        corners = points[ids]
        centre = corners.mean(axis=0)
        u = corners[0] - centre
        u /= np.linalg.norm(u)
        v = np.cross(normal, u)
        angles = np.arctan2((corners - centre) @ v, (corners - centre) @ u)
        faces.append(Face(tuple(int(i) for i in ids[np.argsort(angles)]), normal))
    return faces


def _unique_directions(directions: Array) -> Array:
    """Unit directions with duplicates and opposites removed."""
    kept: list[Array] = []
    for d in directions:
        norm = np.linalg.norm(d)
        if norm < 1e-12:
            continue
        d = d / norm
        if all(abs(float(d @ k)) < 1 - 1e-9 for k in kept):
            kept.append(d)
    return np.array(kept)


@dataclass(frozen=True, eq=False)
class PieceAxes:
    """Face normals and edge directions of a convex piece: the separating-axis candidates."""

    normals: Array  # (F, 3) unit
    edges: Array  # (E, 3) unit


def _piece_axes(points: Array, faces: list[Face] | None = None) -> PieceAxes:
    if faces is None:
        from scipy.spatial import ConvexHull

        faces = _hull_faces(points, ConvexHull(points))
    edges = [points[f.loop[(i + 1) % len(f.loop)]] - points[f.loop[i]] for f in faces for i in range(len(f.loop))]
    return PieceAxes(
        normals=_unique_directions(np.array([f.normal for f in faces])),
        edges=_unique_directions(np.array(edges)),
    )


def _face_triangles(vertices: Array, face: Face) -> list[tuple[int, int, int]]:
    """Triangles of a planar face (indices into `vertices`), wound counter-clockwise from outside."""
    loop = np.array(face.loop)
    if len(loop) == 3:
        return [(int(loop[0]), int(loop[1]), int(loop[2]))]
    corners = vertices[loop] - vertices[loop[0]]
    u = corners[1] / np.linalg.norm(corners[1])
    v = np.cross(face.normal, u)  # (u, v, normal) is right-handed: outside-ccw is ccw in (u, v)
    flat = np.column_stack([corners @ u, corners @ v])
    if polygons.signed_area(flat) < 0:  # guard against a loop given the other way round
        loop, flat = loop[::-1], flat[::-1].copy()
    return [(int(loop[a]), int(loop[b]), int(loop[c])) for a, b, c in polygons.triangulate(flat)]


@dataclass(frozen=True, eq=False)
class PlacedTile:
    """A tile of a structure with its geometry in the structure's frame."""

    tile_id: int
    type_name: str
    shape: TileShape
    rotation: Array  # (3, 3), tile frame -> structure frame
    position: Array  # (3,), origin of the tile frame
    explicit_supports: tuple[int, ...] | None = None

    @cached_property
    def vertices(self) -> Array:
        """(V, 3) corners in the structure frame."""
        return self.shape.vertices @ self.rotation.T + self.position

    @cached_property
    def face_normals(self) -> Array:
        """(F, 3) outward unit normals in the structure frame."""
        return np.array([f.normal for f in self.shape.faces]) @ self.rotation.T

    @cached_property
    def face_offsets(self) -> Array:
        """(F,) plane offsets d so that a point p on face k satisfies normal_k . p = d_k."""
        return np.array(
            [n @ self.vertices[f.loop[0]] for n, f in zip(self.face_normals, self.shape.faces, strict=True)]
        )

    def face_corners(self, k: int) -> Array:
        """(L, 3) corners of face k in the structure frame, counter-clockwise from outside."""
        return self.vertices[list(self.shape.faces[k].loop)]

    @cached_property
    def pieces(self) -> tuple[Array, ...]:
        """Convex pieces' corners in the structure frame."""
        return tuple(p @ self.rotation.T + self.position for p in self.shape.piece_vertices)

    @cached_property
    def piece_axes(self) -> tuple[PieceAxes, ...]:
        """Separating-axis candidates of the convex pieces, in the structure frame."""
        return tuple(
            PieceAxes(a.normals @ self.rotation.T, a.edges @ self.rotation.T)
            for a in self.shape.piece_axes
        )

    @cached_property
    def flat_face_pieces(self) -> tuple[list[Array] | None, ...]:
        """Per face: its convex counter-clockwise x-y pieces when it is horizontal, else None."""
        pieces: list[list[Array] | None] = []
        for k, normal in enumerate(self.face_normals):
            if abs(normal[2]) < 1 - 1e-9:
                pieces.append(None)
                continue
            flat = polygons.counter_clockwise(self.face_corners(k)[:, :2])
            pieces.append([flat] if polygons.is_convex(flat) else [flat[list(t)] for t in polygons.triangulate(flat)])
        return tuple(pieces)

    @property
    def triangles(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(T, 3) indices into `vertices` of a triangulation of the surface, and (T,) face index each."""
        return self.shape.triangles

    @cached_property
    def aabb(self) -> tuple[Array, Array]:
        """Axis-aligned bounding box (min corner, max corner)."""
        return self.vertices.min(axis=0), self.vertices.max(axis=0)

    @cached_property
    def centroid(self) -> Array:
        """Centre of volume in the structure frame (the shape's, moved rigidly: no per-tile work)."""
        return self.shape.centroid @ self.rotation.T + self.position

    @property
    def volume(self) -> float:
        """Volume in cubic metres."""
        return self.shape.volume

    @cached_property
    def footprint(self) -> Array:
        """The tile's outline on the floor plane: (N, 2), counter-clockwise.

        The rotated base polygon for an upright prism (it may be non-convex), otherwise the convex
        hull of the corners projected onto the floor.
        """
        if self.shape.kind == "prism" and abs(self.rotation[2, 2] - 1.0) < 1e-9:
            assert self.shape.polygon is not None
            base = np.column_stack([self.shape.polygon, np.zeros(len(self.shape.polygon))])
            return polygons.counter_clockwise((base @ self.rotation.T + self.position)[:, :2])
        return polygons.convex_hull_2d(self.vertices[:, :2])

    @property
    def yaw(self) -> float:
        return rpy_from_rotation(self.rotation)[2]

    @property
    def quaternion(self) -> tuple[float, float, float, float]:
        return quaternion_from_rotation(self.rotation)


def place_together(tiles: Iterable[PlacedTile]) -> None:
    """Work out the corners, bounding boxes and centroids of many tiles at once, for structures of
    thousands of tiles (tile by tile, these small array operations cost more than their arithmetic).

    Tiles of one shape turned the same way share the turned shape; each adds its own position to
    it, as `PlacedTile.vertices` and `PlacedTile.centroid` do, so the values are the same to the
    last bit. Tiles that have them already are left as they are.
    """
    groups: dict[tuple[int, bytes], list[PlacedTile]] = {}
    for tile in tiles:
        if "vertices" not in tile.__dict__:
            groups.setdefault((id(tile.shape), tile.rotation.tobytes()), []).append(tile)
    for members in groups.values():
        shape, rotation = members[0].shape, members[0].rotation
        positions = np.array([t.position for t in members])
        vertices = (shape.vertices @ rotation.T)[None, :, :] + positions[:, None, :]
        centroids = shape.centroid @ rotation.T + positions
        lows, highs = vertices.min(axis=1), vertices.max(axis=1)
        for tile, corners, low, high, centroid in zip(members, vertices, lows, highs, centroids, strict=True):
            # a cached_property keeps its value in the instance's __dict__, frozen or not
            tile.__dict__.update(vertices=corners, aabb=(low, high), centroid=centroid)


def turn_symmetry(tile: PlacedTile) -> int:
    """How many turns about the vertical through the tile's centroid map it onto itself (1: none)."""
    vertices = tile.vertices - tile.centroid
    if abs(tile.rotation[2, 2] - 1.0) > 1e-6:
        return 1  # not upright: a turn about the vertical is no symmetry to look for
    for order in (8, 6, 5, 4, 3, 2):
        angle = 2 * np.pi / order
        c, s = np.cos(angle), np.sin(angle)
        turned = vertices @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T
        gaps = np.linalg.norm(turned[:, None, :] - vertices[None, :, :], axis=2).min(axis=1)
        if gaps.max() < 1e-3:
            return order
    return 1
