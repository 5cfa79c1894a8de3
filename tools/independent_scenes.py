#!/usr/bin/env python3
"""Independent Kinect v1 inspection scenes, written without any of the project's code.

    tools/workspace-env python tools/independent_scenes.py --out DIR --seed S [--scenes N]
        [--structures paper_14,gate_9] [--sets all|NAME,...] [--grazing-onset DEG] [--grazing-cutoff DEG]

Every scene is one rosbag2 folder (MCAP) with three depth scans of a structure (part built or
complete, some tiles removed or misplaced) from three bearings, as the VI robot's Kinect v1 would
record them, the overhead pose of the robot with each scan, and `truth.json` with what is really
there. The scenes are for measuring `ros2 run vi_node classify` honestly: the structure file is
parsed here, supports are derived here, rays are cast here (numpy, convex polytopes as half-spaces,
no Open3D) and the sensor model is written from HARDWARE.md, so that nothing is shared with
`vi_node`, `tiling_sim` or `tiling_assembly` (a shared bug would cancel out). Score them with
`tools/score_inspection.py`.

Frames: `map` is z up, floor at z = 0; `base_link` x forward, z up; `camera_link` x forward, y left,
z up; `camera_depth_optical_frame` z forward, x right, y down (camera_link -> optical: rpy
(-pi/2, 0, -pi/2)). Lengths in m, angles in rad unless a name says deg.

Model choices worth knowing when reading the numbers:
- the world is an open 30 m floor (no walls unless --room): behind a tile at the low camera's
  height there is often nothing in range, so a removed tile there leaves "no return", not
  "see-through";
- per pixel: a first noiseless cast at the pixel centre (labels, incidence, depth edges), then the
  measured depth from a ray displaced by the lateral noise, axial noise, integer disparity, mm;
- no return: out of 0.5-4.5 m, grazing (ramp from --grazing-onset to --grazing-cutoff), p = 0.5
  next to a depth jump of more than max(1 cm, 4 disparity steps), the projector's shadow, 0.1 %
  speckle;
- a misplaced tile must stay supported (its bottom's centroid over a tile under it) and must not
  overlap another present tile.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import time
import zlib
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

for _threads in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")  # one core: the machine is shared

import numpy as np  # noqa: E402
import yaml  # noqa: E402
from numpy.typing import NDArray  # noqa: E402
from one_line_errors import InputError, OneLineParser, run_command  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
STRUCTURE_DIR = REPO / "config" / "structures"

# --- camera and sensor -------------------------------------------------------------------------

WIDTH, HEIGHT = 640, 480
FX = FY = 580.0
CX, CY = 319.5, 239.5
MIN_RANGE, MAX_RANGE = 0.5, 4.5
PROJECTOR_BASELINE = 0.075  # IR projector along +x of the optical frame (m)
DISPARITY_SLOPE, DISPARITY_OFFSET = -2.85e-3, 3.0  # 1/z = slope * d + offset, d integer

OPTICAL_FRAME = "camera_depth_optical_frame"
CLOUD_TOPIC = "/vi/camera/depth/points"
POSE_TOPIC = "/vi/overhead_pose"

# labels of the label image
NOTHING, FLOOR, CLUTTER, ROBOT, WALL = -1, 0, -2, -3, -4

ROBOT_SIZE = (0.33, 0.33, 0.35)
VI_BASE_RADIUS = 0.18  # the VI robot's round base (m), kept clear of robots and clutter
FLOOR_HALF = 15.0  # the floor is a 30 m square around the structure

HIGH_MOUNT = ((0.08, 0.0, 0.55), (0.0, 0.45, 0.0))
LOW_MOUNT = ((0.10, 0.0, 0.28), (0.0, 0.20, 0.0))

POSITION_BOUND = 0.05  # overhead camera errors (HARDWARE.md, the paper's bounds)
YAW_BOUND = math.radians(10.0)

SCAN_START = 100.0  # s, header stamp of the first scan
SCAN_PERIOD = 1.0
POSE_LEAD = 0.005  # the overhead pose is stamped this much before its scan


@dataclass(frozen=True)
class KinectModel:
    """Kinect v1 depth model (HARDWARE.md: Nguyen, Izadi, Lovell 2012; Khoshelham, Oude Elberink 2012)."""

    grazing_onset_deg: float = 70.0  # return probability 1 up to here ...
    grazing_cutoff_deg: float = 77.0  # ... falling linearly to 0 here
    edge_dropout: float = 0.5  # probability of no return on a pixel next to a depth jump
    edge_min_jump: float = 0.01  # a jump is at least this (m) ...
    edge_disparity_steps: float = 4.0  # ... and this many disparity steps (noise is about one step)
    speckle: float = 0.001  # random dropouts
    shadow_eps: float = 0.002  # a blocker closer than this (m) to either end of the projector ray is ignored


@dataclass(frozen=True)
class SceneSet:
    name: str
    description: str
    mount: tuple[tuple[float, float, float], tuple[float, float, float]]
    bound_errors: bool  # overhead errors exactly at the bounds (else uniform up to them)
    world: bool  # clutter, assembly robots, rocking base and mount calibration error (each can be turned off)
    distance: tuple[float, float] = (0.7, 1.6)
    near_robot: bool = False
    misplace: bool = False
    no_clutter: bool = False  # the no_* switches are for diagnosis only (no shipped set uses them)
    no_robots: bool = False
    no_rocking: bool = False
    no_mount_error: bool = False

    @property
    def clutter(self) -> bool:
        return self.world and not self.no_clutter

    @property
    def robots(self) -> bool:
        return self.world and not self.no_robots

    @property
    def rocking(self) -> bool:
        return self.world and not self.no_rocking

    @property
    def mount_error(self) -> bool:
        return self.world and not self.no_mount_error


SCENE_SETS: dict[str, SceneSet] = {
    s.name: s
    for s in (
        SceneSet("high_clean", "high mount, nothing else in the scene, overhead errors uniform up to the bounds",
                 HIGH_MOUNT, False, False),
        SceneSet("high_world", "high mount, clutter, 1-2 robots near the structure, rocking base, mount "
                 "calibration error, overhead errors at the bounds", HIGH_MOUNT, True, True),
        SceneSet("low_world", "as high_world with the low mount", LOW_MOUNT, True, True),
        SceneSet("low_close", "as low_world, base 0.6-0.9 m from the structure", LOW_MOUNT, True, True,
                 distance=(0.6, 0.9)),
        SceneSet("robots_near_camera", "as high_world plus a robot 0.2-0.45 m in front of the camera, off to "
                 "one side, in every scan", HIGH_MOUNT, True, True, near_robot=True),
        SceneSet("misplaced", "as high_world, 1-2 misplaced tiles (shift, turn or wrong type) and 0-1 removed",
                 HIGH_MOUNT, True, True, misplace=True),
        SceneSet("misplaced_low", "as misplaced with the low mount", LOW_MOUNT, True, True, misplace=True),
    )
}


# --- rotations and transforms ------------------------------------------------------------------

def rot_x(a: float) -> NDArray[np.float64]:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> NDArray[np.float64]:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> NDArray[np.float64]:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_matrix(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    """REP 103 fixed-axis roll, pitch, yaw: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def homogeneous(rotation: NDArray[np.float64], translation: Any) -> NDArray[np.float64]:
    out = np.eye(4)
    out[:3, :3] = rotation
    out[:3, 3] = np.asarray(translation, dtype=float)
    return out


OPTICAL_IN_LINK = homogeneous(rpy_matrix(-math.pi / 2, 0.0, -math.pi / 2), (0.0, 0.0, 0.0))


def wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


# --- 2D polygons -------------------------------------------------------------------------------

def signed_area(poly: NDArray[np.float64]) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def cross2(o: Any, a: Any, b: Any) -> float:
    return float((a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]))


def convex_hull_2d(points: NDArray[np.float64], tol: float = 1e-12) -> NDArray[np.float64]:
    """Counter-clockwise hull (monotone chain), collinear points dropped."""
    pts = sorted({(round(float(p[0]), 9), round(float(p[1]), 9)) for p in points})
    if len(pts) < 3:
        return np.array(pts, dtype=float).reshape(-1, 2)
    lower: list[tuple[float, float]] = []
    for p in pts:
        while len(lower) >= 2 and cross2(lower[-2], lower[-1], p) <= tol:
            lower.pop()
        lower.append(p)
    upper: list[tuple[float, float]] = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross2(upper[-2], upper[-1], p) <= tol:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1], dtype=float)


def clip_convex(subject: NDArray[np.float64], clip: NDArray[np.float64]) -> NDArray[np.float64]:
    """Sutherland-Hodgman: the part of convex `subject` inside convex `clip` (both counter-clockwise)."""
    out = [tuple(p) for p in subject]
    n = len(clip)
    for i in range(n):
        a, b = clip[i], clip[(i + 1) % n]
        if not out:
            break
        inp, out = out, []
        for j in range(len(inp)):
            p, q = inp[j], inp[(j + 1) % len(inp)]
            p_in, q_in = cross2(a, b, p) >= 0, cross2(a, b, q) >= 0
            if p_in:
                out.append(p)
            if p_in != q_in:
                dp, dq = cross2(a, b, p), cross2(a, b, q)
                s = dp / (dp - dq)
                out.append((p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])))
    return np.array(out, dtype=float).reshape(-1, 2)


def overlap_area(a: list[NDArray[np.float64]], b: list[NDArray[np.float64]]) -> float:
    """Area shared by two unions of disjoint convex polygons."""
    total = 0.0
    for pa in a:
        for pb in b:
            piece = clip_convex(pa, pb)
            if len(piece) >= 3:
                total += abs(signed_area(piece))
    return total


def _segments_cross(p1: Any, p2: Any, q1: Any, q2: Any) -> bool:
    d1, d2 = cross2(q1, q2, p1), cross2(q1, q2, p2)
    d3, d4 = cross2(p1, p2, q1), cross2(p1, p2, q2)
    if ((d1 > 0) != (d2 > 0)) and ((d3 > 0) != (d4 > 0)) and 0 not in (d1, d2, d3, d4):
        return True

    def on(a: Any, b: Any, c: Any) -> bool:
        return cross2(a, b, c) == 0 and min(a[0], b[0]) <= c[0] <= max(a[0], b[0]) and (
            min(a[1], b[1]) <= c[1] <= max(a[1], b[1])
        )

    return on(q1, q2, p1) or on(q1, q2, p2) or on(p1, p2, q1) or on(p1, p2, q2)


def is_simple(poly: NDArray[np.float64]) -> bool:
    n = len(poly)
    for i in range(n):
        if np.allclose(poly[i], poly[(i + 1) % n]):
            return False
        for j in range(i + 1, n):
            if j == i or (j + 1) % n == i or (i + 1) % n == j:
                continue
            if _segments_cross(poly[i], poly[(i + 1) % n], poly[j], poly[(j + 1) % n]):
                return False
    return True


def is_convex(poly: NDArray[np.float64]) -> bool:
    """For a counter-clockwise simple polygon."""
    n = len(poly)
    return all(cross2(poly[i], poly[(i + 1) % n], poly[(i + 2) % n]) >= -1e-12 for i in range(n))


def ear_clip(poly: NDArray[np.float64]) -> list[NDArray[np.float64]]:
    """Triangles (counter-clockwise) of a simple counter-clockwise polygon."""
    idx = list(range(len(poly)))
    triangles = []
    guard = 0
    while len(idx) > 3 and guard < 10000:
        guard += 1
        for k in range(len(idx)):
            i0, i1, i2 = idx[k - 1], idx[k], idx[(k + 1) % len(idx)]
            a, b, c = poly[i0], poly[i1], poly[i2]
            if cross2(a, b, c) <= 1e-14:
                continue
            inside = False
            for j in idx:
                if j in (i0, i1, i2):
                    continue
                p = poly[j]
                if cross2(a, b, p) >= 0 and cross2(b, c, p) >= 0 and cross2(c, a, p) >= 0:
                    inside = True
                    break
            if not inside:
                triangles.append(np.array([a, b, c]))
                idx.pop(k)
                break
        else:
            raise InputError("polygon cannot be split into triangles")
    triangles.append(poly[idx])
    return triangles


def convex_distance(a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
    """Distance between two convex polygons (0 when they overlap or touch)."""
    for poly in (a, b):
        n = len(poly)
        for i in range(n):
            e = poly[(i + 1) % n] - poly[i]
            normal = np.array([e[1], -e[0]])
            if np.linalg.norm(normal) == 0:
                continue
            pa, pb = a @ normal, b @ normal
            if pa.max() < pb.min() or pb.max() < pa.min():
                break
        else:
            continue
        break
    else:
        return 0.0  # no separating axis

    def point_segment(p: Any, s0: Any, s1: Any) -> float:
        d = s1 - s0
        t = float(np.clip(np.dot(p - s0, d) / max(np.dot(d, d), 1e-18), 0.0, 1.0))
        return float(np.linalg.norm(p - (s0 + t * d)))

    best = math.inf
    for p_set, q_set in ((a, b), (b, a)):
        for p in p_set:
            for i in range(len(q_set)):
                best = min(best, point_segment(p, q_set[i], q_set[(i + 1) % len(q_set)]))
    return best


def point_in_convex(p: Any, poly: NDArray[np.float64], tol: float = 1e-9) -> bool:
    n = len(poly)
    return all(cross2(poly[i], poly[(i + 1) % n], p) >= -tol for i in range(n))


# --- convex solids -----------------------------------------------------------------------------

@dataclass
class Solid:
    """A convex polytope {x : normals @ x <= offsets} (unit normals) with its vertices."""

    normals: NDArray[np.float64]
    offsets: NDArray[np.float64]
    vertices: NDArray[np.float64]

    @property
    def lower(self) -> NDArray[np.float64]:
        return self.vertices.min(axis=0)

    @property
    def upper(self) -> NDArray[np.float64]:
        return self.vertices.max(axis=0)

    def corners(self) -> NDArray[np.float64]:
        lo, hi = self.lower, self.upper
        return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])

    def footprint(self) -> NDArray[np.float64]:
        return convex_hull_2d(self.vertices[:, :2])


def solid_from_points(points: NDArray[np.float64]) -> Solid:
    from scipy.spatial import ConvexHull, QhullError

    try:
        hull = ConvexHull(points)
    except (QhullError, ValueError) as error:
        raise InputError(f"not a solid: {str(error).splitlines()[0]}") from None
    planes: dict[tuple[float, ...], tuple[NDArray[np.float64], float]] = {}
    for eq in hull.equations:
        n, d = eq[:3], eq[3]
        norm = float(np.linalg.norm(n))
        n, off = n / norm, -d / norm
        key = (*np.round(n, 6), round(off, 7))
        planes.setdefault(key, (n, off))
    normals = np.array([p[0] for p in planes.values()])
    offsets = np.array([p[1] for p in planes.values()])
    return Solid(normals, offsets, points[hull.vertices].copy())


def box_solid(x: float, y: float, yaw: float, size: tuple[float, float, float], z0: float = 0.0) -> Solid:
    lx, ly, lz = size
    local = np.array([[sx * lx / 2, sy * ly / 2, z] for sx in (-1, 1) for sy in (-1, 1) for z in (0.0, lz)])
    return solid_from_points(local @ rot_z(yaw).T + np.array([x, y, z0]))


def solids_overlap(a: Solid, b: Solid, depth: float = 5e-4) -> bool:
    """Whether the interiors share a ball of radius `depth` (touching faces do not overlap)."""
    if np.any(a.lower > b.upper - depth) or np.any(b.lower > a.upper - depth):
        return False
    from scipy.optimize import linprog

    normals = np.vstack([a.normals, b.normals])
    offsets = np.concatenate([a.offsets, b.offsets])
    a_ub = np.hstack([normals, np.ones((len(normals), 1))])
    res = linprog(
        c=[0, 0, 0, -1], A_ub=a_ub, b_ub=offsets, bounds=[(None, None)] * 3 + [(None, 1.0)], method="highs"
    )
    return bool(res.status == 0 and -res.fun > depth)


# --- structure files ---------------------------------------------------------------------------

@dataclass
class TileType:
    name: str
    pieces: list[NDArray[np.float64]]  # convex pieces, vertices in the tile frame
    height: float
    size_cm: tuple[float, float, float]  # bounding box in the tile frame (cm)


@dataclass
class Tile:
    id: int
    type: str
    position: NDArray[np.float64]
    rotation: NDArray[np.float64]
    yaw: float  # for 2D moves (0 when given as rpy with roll/pitch)


@dataclass
class PlacedTile:
    """A tile at a pose in the map: its convex pieces and faces."""

    id: int
    type: str
    position: NDArray[np.float64]
    rotation: NDArray[np.float64]
    solids: list[Solid]
    zmin: float
    zmax: float
    top: list[NDArray[np.float64]]  # convex polygons of the top face (xy)
    bottom: list[NDArray[np.float64]]
    footprint: list[NDArray[np.float64]]  # xy hull of each piece


@dataclass
class Structure:
    name: str
    path: Path
    types: dict[str, TileType]
    tiles: dict[int, Tile]
    placed: dict[int, PlacedTile] = field(default_factory=dict)
    rests_on: dict[int, set[int]] = field(default_factory=dict)  # tile -> tiles it rests on


def _number(value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"{what} must be a finite number, got {value!r}")
    return float(value)


def _vector(value: Any, count: int, what: str) -> list[float]:
    if not isinstance(value, list) or len(value) != count:
        raise InputError(f"{what} must be a list of {count} numbers, got {value!r}")
    return [_number(v, what) for v in value]


def _tile_type(name: str, spec: Any) -> TileType:
    where = f"tile type '{name}'"
    if not isinstance(spec, dict):
        raise InputError(f"{where}: must be a mapping")
    unknown = set(spec) - {"prism", "convex", "attachment_sites"}
    if unknown:
        raise InputError(f"{where}: unknown keys {sorted(unknown)}")
    if ("prism" in spec) == ("convex" in spec):
        raise InputError(f"{where}: needs exactly one of 'prism' and 'convex'")
    if "prism" in spec:
        prism = spec["prism"]
        if not isinstance(prism, dict) or set(prism) != {"polygon", "height"}:
            raise InputError(f"{where}: prism needs exactly 'polygon' and 'height'")
        if not isinstance(prism["polygon"], list) or len(prism["polygon"]) < 3:
            raise InputError(f"{where}: polygon needs at least 3 corners")
        poly = np.array([_vector(p, 2, f"{where}: polygon corner") for p in prism["polygon"]])
        height = _number(prism["height"], f"{where}: height")
        if height <= 0:
            raise InputError(f"{where}: height must be positive, got {height}")
        if not is_simple(poly):
            raise InputError(f"{where}: polygon is not simple (edges cross or corners repeat)")
        area = signed_area(poly)
        if abs(area) < 1e-10:
            raise InputError(f"{where}: polygon has no area")
        if area < 0:
            poly = poly[::-1].copy()
        polys = [poly] if is_convex(poly) else ear_clip(poly)
        pieces = [np.vstack([np.c_[p, np.zeros(len(p))], np.c_[p, np.full(len(p), height)]]) for p in polys]
    else:
        convex = spec["convex"]
        if not isinstance(convex, dict) or set(convex) != {"vertices"} or not isinstance(convex["vertices"], list):
            raise InputError(f"{where}: convex needs exactly 'vertices'")
        pts = np.array([_vector(p, 3, f"{where}: vertex") for p in convex["vertices"]])
        if len(pts) < 4:
            raise InputError(f"{where}: a convex tile needs at least 4 vertices")
        try:
            solid = solid_from_points(pts)
        except InputError as error:
            raise InputError(f"{where}: {error}") from None
        if len(solid.vertices) != len(pts):
            raise InputError(f"{where}: vertices are not those of a convex polytope (some lie inside)")
        pieces = [pts]
        height = float(pts[:, 2].max() - pts[:, 2].min())
    allpts = np.vstack(pieces)
    ext = allpts.max(axis=0) - allpts.min(axis=0)
    for piece in pieces:
        try:
            solid_from_points(piece)  # fails on a flat piece
        except InputError as error:
            raise InputError(f"{where}: {error}") from None
    size = (round(ext[0] * 100, 1), round(ext[1] * 100, 1), round(ext[2] * 100, 1))
    return TileType(name, pieces, height, size)


def place(tile_id: int, ttype: TileType, position: Any, rotation: NDArray[np.float64]) -> PlacedTile:
    position = np.asarray(position, dtype=float)
    solids = [solid_from_points(piece @ rotation.T + position) for piece in ttype.pieces]
    zmin = min(float(s.lower[2]) for s in solids)
    zmax = max(float(s.upper[2]) for s in solids)

    def face(level: float) -> list[NDArray[np.float64]]:
        polys = []
        for s in solids:
            pts = s.vertices[np.abs(s.vertices[:, 2] - level) <= 1e-3]
            if len(pts) >= 3:
                hull = convex_hull_2d(pts[:, :2])
                if len(hull) >= 3 and abs(signed_area(hull)) > 1e-9:
                    polys.append(hull)
        return polys

    return PlacedTile(
        tile_id, ttype.name, position, rotation, solids, zmin, zmax, face(zmax), face(zmin),
        [s.footprint() for s in solids],
    )


class _DuplicateKeyError(Exception):
    pass


class _StrictLoader(yaml.SafeLoader):
    """PyYAML's safe loader, refusing a key given twice in one mapping."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        keys = [self.construct_object(k, deep=deep) for k, _ in node.value]
        for key in keys:
            if keys.count(key) > 1:
                raise _DuplicateKeyError(f"key {key!r} given twice (line {node.start_mark.line + 1})")
        return super().construct_mapping(node, deep=deep)


def load_structure(path_text: str) -> Structure:
    path = Path(path_text)
    if not path.suffix and not path.exists():
        path = STRUCTURE_DIR / f"{path_text}.yaml"
    if not path.is_file():
        raise InputError(f"{path_text}: no such structure file (nor {STRUCTURE_DIR}/{path_text}.yaml)")
    try:
        data = yaml.load(path.read_text(encoding="utf-8"), Loader=_StrictLoader)  # a SafeLoader
    except _DuplicateKeyError as error:
        raise InputError(f"{path}: {error}") from None
    except (yaml.YAMLError, UnicodeDecodeError) as error:
        raise InputError(f"{path}: not valid YAML: {str(error).splitlines()[0]}") from None
    try:
        return _structure(path, data)
    except InputError as error:
        raise InputError(f"{path}: {error}") from None


def _structure(path: Path, data: Any) -> Structure:
    if not isinstance(data, dict):
        raise InputError("must be a mapping with 'tile_types' and 'tiles'")
    unknown = set(data) - {"name", "frame_id", "tile_types", "tiles", "caches"}
    if unknown:
        raise InputError(f"unknown keys {sorted(unknown)}")
    if data.get("frame_id", "map") != "map":
        raise InputError(f"frame_id must be 'map', got {data.get('frame_id')!r}")
    types_spec, tiles_spec = data.get("tile_types"), data.get("tiles")
    if not isinstance(types_spec, dict) or not types_spec:
        raise InputError("'tile_types' must be a non-empty mapping")
    if not isinstance(tiles_spec, list) or not tiles_spec:
        raise InputError("'tiles' must be a non-empty list")
    types = {str(name): _tile_type(str(name), spec) for name, spec in types_spec.items()}
    caches = data.get("caches") or {}
    if not isinstance(caches, dict) or any(str(k) not in types for k in caches):
        raise InputError(f"caches must map known tile types to [x, y], got {caches!r}")
    tiles: dict[int, Tile] = {}
    explicit: dict[int, list[int]] = {}
    for entry in tiles_spec:
        if not isinstance(entry, dict):
            raise InputError(f"a tile must be a mapping, got {entry!r}")
        unknown = set(entry) - {"id", "type", "position", "yaw", "rpy", "supports"}
        if unknown:
            raise InputError(f"tile {entry.get('id')}: unknown keys {sorted(unknown)}")
        tid = entry.get("id")
        if isinstance(tid, bool) or not isinstance(tid, int) or tid <= 0:
            raise InputError(f"tile id must be a positive integer, got {tid!r}")
        if tid in tiles:
            raise InputError(f"duplicate tile id {tid}")
        if entry.get("type") not in types:
            raise InputError(f"tile {tid}: unknown type {entry.get('type')!r}")
        position = _vector(entry.get("position"), 3, f"tile {tid}: position")
        if "yaw" in entry and "rpy" in entry:
            raise InputError(f"tile {tid}: give yaw or rpy, not both")
        if "rpy" in entry:
            r, p, y = _vector(entry["rpy"], 3, f"tile {tid}: rpy")
        else:
            r, p, y = 0.0, 0.0, _number(entry.get("yaw", 0.0), f"tile {tid}: yaw")
        if "supports" in entry:
            sup = entry["supports"]
            if not isinstance(sup, list) or any(isinstance(s, bool) or not isinstance(s, int) for s in sup):
                raise InputError(f"tile {tid}: supports must be a list of tile ids")
            explicit[tid] = list(sup)
        yaw = y if abs(r) < 1e-9 and abs(p) < 1e-9 else 0.0
        tiles[tid] = Tile(tid, entry["type"], np.array(position), rpy_matrix(r, p, y), yaw)
    structure = Structure(str(data.get("name", path.stem)), path, types, tiles)
    for tid, tile in tiles.items():
        structure.placed[tid] = place(tid, types[tile.type], tile.position, tile.rotation)
        if structure.placed[tid].zmin < -1e-3:
            raise InputError(f"tile {tid} reaches below the floor (z = {structure.placed[tid].zmin:.4f})")
    ids = sorted(tiles)
    for i, a in enumerate(ids):
        for b in ids[i + 1:]:
            if any(solids_overlap(sa, sb) for sa in structure.placed[a].solids for sb in structure.placed[b].solids):
                raise InputError(f"tiles {a} and {b} overlap")
    structure.rests_on = derive_supports(structure.placed)
    for tid, sup in explicit.items():
        missing = set(sup) - set(tiles)
        if missing:
            raise InputError(f"tile {tid}: supports name unknown tiles {sorted(missing)}")
        structure.rests_on[tid] = set(sup)
    for tid in ids:
        if structure.placed[tid].zmin > 1e-3 and not structure.rests_on[tid]:
            raise InputError(f"tile {tid} floats (nothing under it, not on the floor)")
    topological_order(structure.rests_on, np.random.default_rng(0))  # fails on a cycle
    return structure


def derive_supports(placed: dict[int, PlacedTile], min_area: float = 1e-6) -> dict[int, set[int]]:
    """Tile b rests on tile a when b's bottom is at a's top height (1 mm) over a positive footprint overlap."""
    rests_on: dict[int, set[int]] = {tid: set() for tid in placed}
    for b, tb in placed.items():
        if tb.zmin <= 1e-3:
            continue
        for a, ta in placed.items():
            if a != b and abs(tb.zmin - ta.zmax) <= 1e-3 and overlap_area(tb.bottom, ta.top) > min_area:
                rests_on[b].add(a)
    return rests_on


def topological_order(rests_on: dict[int, set[int]], rng: np.random.Generator) -> list[int]:
    """A random order in which every tile comes after the tiles it rests on."""
    order: list[int] = []
    done: set[int] = set()
    remaining = sorted(rests_on)
    while remaining:
        ready = [t for t in remaining if rests_on[t] <= done]
        if not ready:
            raise InputError(f"support cycle among tiles {remaining}")
        pick = ready[int(rng.integers(len(ready)))]
        order.append(pick)
        done.add(pick)
        remaining.remove(pick)
    return order


# --- ray casting -------------------------------------------------------------------------------

@dataclass
class Hits:
    depth: NDArray[np.float64]  # ray parameter; for camera rays with direction z = 1, the optical depth
    normal: NDArray[np.float64]  # (N, 3) map frame
    label: NDArray[np.int32]


def _ray_window(
    solid: Solid, origin: NDArray[np.float64], rotation: NDArray[np.float64], pu: NDArray[np.float64],
    pv: NDArray[np.float64],
) -> NDArray[np.intp] | None:
    """Rays whose image coordinates fall in the solid's bounding box projected into the image
    (None: the solid lies behind the camera)."""
    cam = (solid.corners() - origin) @ rotation
    z = cam[:, 2]
    if z.max() <= 1e-6:
        return None
    if z.min() <= 1e-3:
        return np.arange(len(pu))  # straddles the image plane: no culling
    u = FX * cam[:, 0] / z + CX
    v = FY * cam[:, 1] / z + CY
    mask = (pu >= u.min() - 1) & (pu <= u.max() + 1) & (pv >= v.min() - 1) & (pv <= v.max() + 1)
    return np.flatnonzero(mask)


def _slab(
    solid: Solid, origin: NDArray[np.float64], dirs: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.intp]]:
    """Cyrus-Beck clipping of rays origin + t dirs against a convex solid: t_in, t_out, entering plane."""
    nd = dirs @ solid.normals.T  # (M, k)
    num = solid.offsets - solid.normals @ origin  # (k,)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = num[None, :] / nd
    entering = np.where(nd < 0, t, -np.inf)
    leaving = np.where(nd > 0, t, np.inf)
    plane = np.argmax(entering, axis=1)
    t_in = entering[np.arange(len(dirs)), plane]
    t_out = leaving.min(axis=1)
    outside_parallel = ((nd == 0) & (num[None, :] < 0)).any(axis=1)
    t_in = np.where(outside_parallel, np.inf, t_in)
    return t_in, t_out, plane


def camera_rays(
    rotation: NDArray[np.float64], u: NDArray[np.float64], v: NDArray[np.float64]
) -> NDArray[np.float64]:
    """Map-frame directions of pixel rays, scaled to optical z = 1."""
    d = np.stack([(u - CX) / FX, (v - CY) / FY, np.ones_like(u)], axis=1)
    return d @ rotation.T


def cast(
    objects: list[tuple[int, Solid]], origin: NDArray[np.float64], rotation: NDArray[np.float64],
    u: NDArray[np.float64], v: NDArray[np.float64], floor_center: Any = (0.0, 0.0),
) -> Hits:
    """First hits of the camera rays through (u, v) (camera at `origin`, optical->map `rotation`)
    against the floor square and the labelled convex solids."""
    dirs = camera_rays(rotation, u, v)
    n = len(u)
    depth = np.full(n, np.inf)
    label = np.full(n, NOTHING, dtype=np.int32)
    normal = np.zeros((n, 3))
    if origin[2] > 0:
        with np.errstate(divide="ignore", invalid="ignore"):
            tf = -origin[2] / dirs[:, 2]
        px = origin[0] + tf * dirs[:, 0]
        py = origin[1] + tf * dirs[:, 1]
        ok = (dirs[:, 2] < 0) & (np.abs(px - floor_center[0]) <= FLOOR_HALF) & (
            np.abs(py - floor_center[1]) <= FLOOR_HALF
        )
        depth[ok] = tf[ok]
        label[ok] = FLOOR
        normal[ok] = (0.0, 0.0, 1.0)
    for lab, solid in objects:
        sel = _ray_window(solid, origin, rotation, u, v)
        if sel is None or not len(sel):
            continue
        t_in, t_out, plane = _slab(solid, origin, dirs[sel])
        hit = (t_in <= t_out) & (t_in > 1e-6) & (t_in < depth[sel])
        ids = sel[hit]
        depth[ids] = t_in[hit]
        label[ids] = lab
        normal[ids] = solid.normals[plane[hit]]
    return Hits(depth, normal, label)


def blocked_from(
    objects: list[tuple[int, Solid]], source: NDArray[np.float64], rotation: NDArray[np.float64],
    targets: NDArray[np.float64], eps: float,
) -> NDArray[np.bool_]:
    """Whether the segment from `source` to each target point passes through a solid (farther than
    `eps` from both ends). The floor never blocks (both ends lie on or above it)."""
    seg = targets - source
    length = np.linalg.norm(seg, axis=1)
    cam = seg @ rotation
    with np.errstate(divide="ignore", invalid="ignore"):
        pu = FX * cam[:, 0] / cam[:, 2] + CX
        pv = FY * cam[:, 1] / cam[:, 2] + CY
    blocked = np.zeros(len(targets), dtype=bool)
    for _, solid in objects:
        sel = _ray_window(solid, source, rotation, pu, pv)
        if sel is None or not len(sel):
            continue
        t_in, t_out, _ = _slab(solid, source, seg[sel])
        margin = eps / np.maximum(length[sel], 1e-9)
        blocked[sel] |= np.maximum(t_in, margin) < np.minimum(t_out, 1.0 - margin)
    return blocked


# --- the Kinect --------------------------------------------------------------------------------

def axial_sigma(z: NDArray[np.float64], theta: NDArray[np.float64]) -> NDArray[np.float64]:
    sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
    steep = theta > math.radians(60.0)
    th = np.minimum(theta, math.radians(89.5))
    extra = 0.0001 / np.sqrt(np.maximum(z, 1e-3)) * th**2 / (math.pi / 2 - th) ** 2
    return np.where(steep, sigma + extra, sigma)


def lateral_sigma_px(theta: NDArray[np.float64]) -> NDArray[np.float64]:
    th = np.minimum(theta, math.radians(89.5))
    return 0.8 + 0.035 * th / (math.pi / 2 - th)


def quantise(z: NDArray[np.float64]) -> NDArray[np.float64]:
    """Integer disparity, then millimetres."""
    with np.errstate(divide="ignore", invalid="ignore"):
        d = np.rint((1.0 / z - DISPARITY_OFFSET) / DISPARITY_SLOPE)
        zq = 1.0 / (DISPARITY_SLOPE * d + DISPARITY_OFFSET)
    return np.rint(zq * 1000.0) / 1000.0


def incidence(hits: Hits, dirs: NDArray[np.float64]) -> NDArray[np.float64]:
    unit = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    cosang = np.abs(np.einsum("ij,ij->i", unit, hits.normal))
    theta = np.arccos(np.clip(cosang, 0.0, 1.0))
    return np.where(hits.label == NOTHING, 0.0, theta)


def depth_jumps(z: NDArray[np.float64], model: KinectModel) -> NDArray[np.bool_]:
    """Pixels next to a depth jump well above the noise (z: H x W, inf where nothing)."""
    mask = np.zeros(z.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        for a, b, sa, sb in (
            (z[:, :-1], z[:, 1:], (slice(None), slice(None, -1)), (slice(None), slice(1, None))),
            (z[:-1, :], z[1:, :], (slice(None, -1), slice(None)), (slice(1, None), slice(None))),
        ):
            near = np.minimum(a, b)
            threshold = np.maximum(model.edge_min_jump, model.edge_disparity_steps * 2.85e-3 * near**2)
            jump = (np.abs(a - b) > threshold) & np.isfinite(near)
            mask[sa] |= jump
            mask[sb] |= jump
    return mask & np.isfinite(z)


@dataclass
class Scan:
    points: NDArray[np.float32]  # H x W x 3, optical frame, NaN where no return
    label: NDArray[np.int32]  # noiseless label image at pixel centres
    depth: NDArray[np.float64]  # noiseless depth at pixel centres (inf where nothing)
    measured_label: NDArray[np.int32]  # label of the surface each return came from
    valid: NDArray[np.bool_]
    dropouts: dict[str, int]
    shadow: NDArray[np.bool_]


def simulate_kinect(
    objects: list[tuple[int, Solid]], optical_pose: NDArray[np.float64], rng: np.random.Generator,
    model: KinectModel, floor_center: Any = (0.0, 0.0), noise: bool = True,
) -> Scan:
    """One organized Kinect v1 cloud of the world `objects` seen from `optical_pose` (4x4, map)."""
    rotation, origin = optical_pose[:3, :3], optical_pose[:3, 3]
    vv, uu = np.mgrid[0:HEIGHT, 0:WIDTH]
    u = uu.ravel().astype(float)
    v = vv.ravel().astype(float)
    ideal = cast(objects, origin, rotation, u, v, floor_center)
    theta0 = incidence(ideal, camera_rays(rotation, u, v))
    if noise:
        sl = lateral_sigma_px(theta0)
        ud = u + rng.normal(0.0, 1.0, u.shape) * sl
        vd = v + rng.normal(0.0, 1.0, v.shape) * sl
    else:
        ud, vd = u, v
    dirs = camera_rays(rotation, ud, vd)
    hits = cast(objects, origin, rotation, ud, vd, floor_center)
    theta = incidence(hits, dirs)
    z_true = hits.depth
    something = hits.label != NOTHING
    z = z_true.copy()
    if noise:
        z[something] += rng.normal(0.0, 1.0, int(something.sum())) * axial_sigma(z_true[something], theta[something])
    zq = np.full_like(z, np.nan)
    zq[something] = quantise(z[something])
    valid = something & (zq >= MIN_RANGE) & (zq <= MAX_RANGE)
    dropouts = {"nothing": int((~something).sum()), "range": int((something & ~valid).sum())}
    shadow = np.zeros(len(u), dtype=bool)
    if noise:
        onset, cutoff = math.radians(model.grazing_onset_deg), math.radians(model.grazing_cutoff_deg)
        p_return = np.clip((cutoff - theta) / max(cutoff - onset, 1e-9), 0.0, 1.0)
        grazing = valid & (rng.random(len(u)) >= p_return)
        valid &= ~grazing
        edges = depth_jumps(ideal.depth.reshape(HEIGHT, WIDTH), model).ravel()
        edge_drop = valid & edges & (rng.random(len(u)) < model.edge_dropout)
        valid &= ~edge_drop
        projector = origin + rotation[:, 0] * PROJECTOR_BASELINE
        idx = np.flatnonzero(valid)
        targets = origin + dirs[idx] * z_true[idx, None]
        shadow[idx] = blocked_from(objects, projector, rotation, targets, model.shadow_eps)
        valid &= ~shadow
        speckle = valid & (rng.random(len(u)) < model.speckle)
        valid &= ~speckle
        dropouts.update(grazing=int(grazing.sum()), edge=int(edge_drop.sum()), shadow=int(shadow.sum()),
                        speckle=int(speckle.sum()))
    zs = np.where(valid, zq, np.nan)
    points = np.stack([(u - CX) * zs / FX, (v - CY) * zs / FY, zs], axis=1).astype(np.float32)
    return Scan(
        points.reshape(HEIGHT, WIDTH, 3), ideal.label.reshape(HEIGHT, WIDTH), ideal.depth.reshape(HEIGHT, WIDTH),
        hits.label.reshape(HEIGHT, WIDTH), valid.reshape(HEIGHT, WIDTH), dropouts, shadow.reshape(HEIGHT, WIDTH),
    )


# --- scenes ------------------------------------------------------------------------------------

@dataclass
class Box:
    name: str
    kind: str  # robot | box | tile
    x: float
    y: float
    yaw: float
    size: tuple[float, float, float]
    solids: list[Solid]
    tile_type: str = ""

    def footprint(self) -> list[NDArray[np.float64]]:
        return [s.footprint() for s in self.solids]

    def record(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "kind": self.kind, "x": round(self.x, 5), "y": round(self.y, 5),
                               "yaw": round(self.yaw, 5), "size": [round(s, 4) for s in self.size]}
        if self.tile_type:
            out["tile_type"] = self.tile_type
        return out


def gap(a: list[NDArray[np.float64]], b: list[NDArray[np.float64]]) -> float:
    return min(convex_distance(pa, pb) for pa in a for pb in b)


def circle_poly(x: float, y: float, r: float, n: int = 16) -> NDArray[np.float64]:
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    return np.c_[x + r * np.cos(ang), y + r * np.sin(ang)]


def overhead_error(rng: np.random.Generator, at_bounds: bool) -> tuple[float, float, float]:
    """(dx, dy, dyaw): exactly at the bounds, or uniform up to them."""
    direction = rng.uniform(-math.pi, math.pi)
    if at_bounds:
        dist, dyaw = POSITION_BOUND, YAW_BOUND * (1 if rng.random() < 0.5 else -1)
    else:
        dist, dyaw = rng.uniform(0.0, POSITION_BOUND), rng.uniform(-YAW_BOUND, YAW_BOUND)
    return dist * math.cos(direction), dist * math.sin(direction), dyaw


def pose_matrix(x: float, y: float, z: float, roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    return homogeneous(rpy_matrix(roll, pitch, yaw), (x, y, z))


def removable(present: set[int], rests_on: dict[int, set[int]]) -> list[int]:
    """Present tiles that no present tile rests on."""
    return sorted(t for t in present if not any(t in rests_on[o] for o in present if o != t))


class SceneBuilder:
    def __init__(self, structure: Structure, scene_set: SceneSet, rng: np.random.Generator, model: KinectModel):
        self.s = structure
        self.set = scene_set
        self.rng = rng
        self.model = model
        self.room: float | None = None  # walls of a square room this far from the structure's centre

    # structure state ------------------------------------------------------------------------
    def choose_tiles(self) -> None:
        rng, s = self.rng, self.s
        order = topological_order(s.rests_on, rng)
        n = len(order)
        self.part_built = bool(rng.random() < 0.3 and n > 3)
        if self.part_built:
            k = int(rng.integers(max(3, math.ceil(n / 3)), n))  # a proper prefix
            self.expected = order[:k]
        else:
            self.expected = list(order)
        present = set(self.expected)
        if self.set.misplace:
            n_remove = int(rng.integers(0, 2))
        else:
            n_remove = int(rng.integers(1, 4))
        self.removed: list[int] = []
        for _ in range(n_remove):
            cand = removable(present, s.rests_on)
            if len(present) <= 2 or not cand:
                break
            pick = cand[int(rng.integers(len(cand)))]
            self.removed.append(pick)
            present.discard(pick)
        self.actual: dict[int, PlacedTile] = {t: s.placed[t] for t in sorted(present)}
        self.misplaced: list[dict[str, Any]] = []
        if self.set.misplace:
            self.misplace(int(rng.integers(1, 3)))

    def _supported(self, tile: PlacedTile, others: dict[int, PlacedTile]) -> bool:
        """On the floor, or its bottom's centroid over the top of a tile right under it."""
        if tile.zmin <= 1e-3:
            return True
        pts = np.vstack(tile.bottom) if tile.bottom else np.vstack(tile.footprint)
        centroid = pts.mean(axis=0)
        for other in others.values():
            if other.id != tile.id and abs(other.zmax - tile.zmin) <= 1e-3:
                if any(point_in_convex(centroid, poly, tol=1e-6) for poly in other.top):
                    return True
        return False

    def _fits(self, tile: PlacedTile, others: dict[int, PlacedTile]) -> bool:
        for other in others.values():
            if other.id == tile.id:
                continue
            if any(solids_overlap(a, b) for a in tile.solids for b in other.solids):
                return False
        return self._supported(tile, others)

    def misplace(self, count: int) -> None:
        rng, s = self.rng, self.s
        for _ in range(count):
            present = set(self.actual)
            done = {m["id"] for m in self.misplaced}
            candidates = [t for t in removable(present, s.rests_on) if t not in done]
            rng.shuffle(candidates)
            for tid in candidates:
                entry = self._misplace_one(tid)
                if entry is not None:
                    self.misplaced.append(entry)
                    break

    def _misplace_one(self, tid: int) -> dict[str, Any] | None:
        rng, s = self.rng, self.s
        tile = s.tiles[tid]
        planned = s.placed[tid]
        flat = bool(np.allclose(tile.rotation[2], (0, 0, 1)))
        kinds = ["shift", "turn", "wrong_type"] if flat else ["shift"]
        ttype = s.types[tile.type]
        same_height = [n for n, t in s.types.items() if n != tile.type and abs(t.height - ttype.height) < 1e-6]
        if not same_height:
            kinds = [k for k in kinds if k != "wrong_type"]
        for _ in range(40):
            kind = kinds[int(rng.integers(len(kinds)))]
            entry: dict[str, Any] = {"id": tid, "kind": kind}
            if kind == "shift":
                dist, ang = rng.uniform(0.02, 0.05), rng.uniform(-math.pi, math.pi)
                offset = np.array([dist * math.cos(ang), dist * math.sin(ang), 0.0])
                moved = place(tid, ttype, tile.position + offset, tile.rotation)
                entry["offset"] = [round(float(offset[0]), 5), round(float(offset[1]), 5)]
            elif kind == "turn":
                turn = rng.uniform(math.radians(15), math.radians(45)) * (1 if rng.random() < 0.5 else -1)
                centroid = np.array([*_centroid_xy(planned), 0.0])
                rz = rot_z(turn)
                position = centroid + rz @ (tile.position - centroid)
                moved = place(tid, ttype, position, rz @ tile.rotation)
                entry["turn"] = round(float(turn), 5)
            else:
                other = same_height[int(rng.integers(len(same_height)))]
                moved = place(tid, s.types[other], tile.position, tile.rotation)
                moved.type = other
                entry["wrong_type"] = other
            if abs(moved.zmin - planned.zmin) > 1e-6:
                continue
            if self._fits(moved, self.actual):
                self.actual[tid] = moved
                entry["pose"] = {"position": [round(float(x), 5) for x in moved.position],
                                 "yaw": round(math.atan2(moved.rotation[1, 0], moved.rotation[0, 0]), 5)}
                return entry
        return None

    # layout ---------------------------------------------------------------------------------
    def structure_outline(self) -> list[NDArray[np.float64]]:
        polys = [p for t in self.expected for p in self.s.placed[t].footprint]
        polys += [p for t in self.actual.values() for p in t.footprint]
        return polys

    def layout(self) -> None:
        rng = self.rng
        outline = self.structure_outline()
        allpts = np.vstack(outline)
        self.center = (allpts.min(axis=0) + allpts.max(axis=0)) / 2
        while True:
            bearings = rng.uniform(-math.pi, math.pi, 3)
            diffs = [abs(wrap(bearings[i] - bearings[j])) for i in range(3) for j in range(i + 1, 3)]
            if min(diffs) >= math.radians(60):
                break
        self.bases = []
        for b in bearings:
            dist = rng.uniform(*self.set.distance)
            x, y = self.center + dist * np.array([math.cos(b), math.sin(b)])
            yaw = wrap(b + math.pi + rng.uniform(-math.radians(5), math.radians(5)))
            self.bases.append({"bearing": float(b), "distance": float(dist), "x": float(x), "y": float(y),
                               "yaw": float(yaw)})
        base_polys = [circle_poly(b["x"], b["y"], VI_BASE_RADIUS) for b in self.bases]
        for poly in base_polys:
            if gap([poly], outline) < 0.02:
                raise _LayoutError("VI base on the structure")
        nominal_xyz, nominal_rpy = self.set.mount
        if self.set.mount_error:
            dxyz = rng.uniform(-0.005, 0.005, 3)
            drpy = rng.uniform(-math.radians(1), math.radians(1), 3)
        else:
            dxyz, drpy = np.zeros(3), np.zeros(3)
        self.true_mount = (np.array(nominal_xyz) + dxyz, np.array(nominal_rpy) + drpy)
        self.near_robots: list[Box | None] = [None, None, None]
        self.robots: list[Box] = []
        self.clutter: list[Box] = []
        obstacles: list[list[NDArray[np.float64]]] = []
        if self.set.near_robot:
            for k in range(3):
                self.near_robots[k] = self._near_robot(k, outline, base_polys)
        if self.set.robots:
            for k in range(int(rng.integers(1, 3))):
                robot = self._robot(k, outline, base_polys, obstacles)
                self.robots.append(robot)
                obstacles.append(robot.footprint())
            for near in self.near_robots:
                if near is not None:
                    near.name = f"robot{len(self.robots) + 1}"
        near_fp = [r.footprint() for r in self.near_robots if r is not None]
        if self.set.clutter:
            for k in range(int(rng.integers(1, 4))):
                size = (rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.2), rng.uniform(0.05, 0.2))
                self.clutter.append(self._clutter(f"box{k + 1}", size, outline, base_polys, obstacles + near_fp))
                obstacles.append(self.clutter[-1].footprint())
            for k in range(int(rng.integers(0, 3))):
                names = sorted(self.s.types)
                self.clutter.append(self._clutter(f"loose_tile{k + 1}", names[int(rng.integers(len(names)))],
                                                  outline, base_polys, obstacles + near_fp))
                obstacles.append(self.clutter[-1].footprint())

    def _robot(self, k: int, outline: list[NDArray[np.float64]], base_polys: list[NDArray[np.float64]],
               obstacles: list[list[NDArray[np.float64]]]) -> Box:
        rng = self.rng
        reach = float(np.max(np.linalg.norm(np.vstack(outline) - self.center, axis=1)))
        for _ in range(2000):
            ang, r = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, reach + 0.5)
            x, y = self.center + r * np.array([math.cos(ang), math.sin(ang)])
            yaw = rng.uniform(-math.pi, math.pi)
            robot = Box(f"robot{k + 1}", "robot", float(x), float(y), float(yaw), ROBOT_SIZE,
                        [box_solid(x, y, yaw, ROBOT_SIZE)])
            fp = robot.footprint()
            if not 0.03 <= gap(fp, outline) <= 0.15:
                continue
            if gap(fp, base_polys) < 0.03 or any(gap(fp, o) < 0.05 for o in obstacles):
                continue
            return robot
        raise _LayoutError("no room for a robot")

    def _near_robot(self, k: int, outline: list[NDArray[np.float64]],
                    base_polys: list[NDArray[np.float64]]) -> Box:
        rng = self.rng
        base = self.bases[k]
        nominal_xyz = self.set.mount[0]
        for _ in range(500):
            r = rng.uniform(0.2, 0.45)  # camera to the robot's near face, along the camera's heading
            side = 1 if rng.random() < 0.5 else -1
            half_view = r * (CX / FX)  # half the image width at that distance
            inner = rng.uniform(0.25, 0.8) * half_view  # the robot's inner edge, off the image centre
            yaw_rel = rng.uniform(-math.radians(20), math.radians(20))
            ahead = nominal_xyz[0] + r + ROBOT_SIZE[0] / 2
            lateral = side * (inner + ROBOT_SIZE[1] / 2)
            c, s_ = math.cos(base["yaw"]), math.sin(base["yaw"])
            x = base["x"] + c * ahead - s_ * lateral
            y = base["y"] + s_ * ahead + c * lateral
            yaw = wrap(base["yaw"] + yaw_rel)
            robot = Box("robot_near", "robot", x, y, yaw, ROBOT_SIZE, [box_solid(x, y, yaw, ROBOT_SIZE)])
            fp = robot.footprint()
            if gap(fp, outline) < 0.03 or gap(fp, base_polys) < 0.02:
                continue
            robot.size = ROBOT_SIZE
            return robot
        raise _LayoutError("no room for a robot in front of the camera")

    def _clutter(self, name: str, what: Any, outline: list[NDArray[np.float64]],
                 base_polys: list[NDArray[np.float64]], obstacles: list[list[NDArray[np.float64]]]) -> Box:
        rng = self.rng
        reach = float(np.max(np.linalg.norm(np.vstack(outline) - self.center, axis=1)))
        for _ in range(2000):
            ang, r = rng.uniform(-math.pi, math.pi), rng.uniform(0.0, reach + 0.6)
            x, y = self.center + r * np.array([math.cos(ang), math.sin(ang)])
            yaw = rng.uniform(-math.pi, math.pi)
            if isinstance(what, str):
                ttype = self.s.types[what]
                pts = np.vstack(ttype.pieces)
                lift = -float(pts[:, 2].min())
                placed = place(0, ttype, (x, y, lift), rot_z(yaw))
                ext = np.vstack([sd.vertices for sd in placed.solids])
                size = tuple(float(v) for v in ext.max(axis=0) - ext.min(axis=0))
                item = Box(name, "tile", float(x), float(y), float(yaw), size, placed.solids, tile_type=what)
            else:
                item = Box(name, "box", float(x), float(y), float(yaw), what, [box_solid(x, y, yaw, what)])
            fp = item.footprint()
            if not 0.08 <= gap(fp, outline) <= 0.40:
                continue
            if gap(fp, base_polys) < 0.03 or any(gap(fp, o) < 0.02 for o in obstacles):
                continue
            return item
        raise _LayoutError("no room for clutter")

    def walls(self) -> list[Solid]:
        """Four walls, 10 cm thick and 2.5 m high, `room` m from the structure's centre (none by default)."""
        if not self.room:
            return []
        h, (cx, cy) = self.room, self.center
        span = (0.1, 2 * h + 0.2, 2.5)
        return [box_solid(cx + dx * (h + 0.05), cy + dy * (h + 0.05), 0.0 if dx else math.pi / 2, span)
                for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))]

    # scans ----------------------------------------------------------------------------------
    def scans(self) -> list[dict[str, Any]]:
        rng = self.rng
        tiles_now = [(tid, sd) for tid, t in self.actual.items() for sd in t.solids]
        tiles_planned = [(tid, sd) for tid in self.expected for sd in self.s.placed[tid].solids]
        scans = []
        for k, base in enumerate(self.bases):
            if self.set.rocking:
                dz = rng.uniform(-0.01, 0.01)
                roll, pitch = rng.uniform(-math.radians(1.5), math.radians(1.5), 2)
            else:
                dz, roll, pitch = 0.0, 0.0, 0.0
            base_pose = pose_matrix(base["x"], base["y"], dz, roll, pitch, base["yaw"])
            mount = homogeneous(rpy_matrix(*self.true_mount[1]), self.true_mount[0])
            link = base_pose @ mount
            optical = link @ OPTICAL_IN_LINK
            ex, ey, eyaw = overhead_error(rng, self.set.bound_errors)
            robots = list(self.robots)
            if self.near_robots[k] is not None:
                robots.append(self.near_robots[k])
            others = [(ROBOT, sd) for r in robots for sd in r.solids]
            others += [(CLUTTER, sd) for c in self.clutter for sd in c.solids]
            others += [(WALL, sd) for sd in self.walls()]
            scan = simulate_kinect(tiles_now + others, optical, rng, self.model, self.center)
            grid_u = np.tile(np.arange(WIDTH, dtype=float), HEIGHT)
            grid_v = np.repeat(np.arange(HEIGHT, dtype=float), WIDTH)
            planned = cast(tiles_planned + others, optical[:3, 3], optical[:3, :3], grid_u, grid_v, self.center)
            robot_records = []
            for r in robots:
                rx, ry, ryaw = overhead_error(rng, True)
                rec = r.record()
                rec["overhead"] = {"x": round(r.x + rx, 5), "y": round(r.y + ry, 5),
                                   "yaw": round(wrap(r.yaw + ryaw), 5)}
                robot_records.append(rec)
            stamp = SCAN_START + k * SCAN_PERIOD
            labels, counts = np.unique(scan.label, return_counts=True)
            seen = dict(zip(labels.tolist(), counts.tolist(), strict=True))
            ret_labels, ret_counts = np.unique(scan.measured_label[scan.valid], return_counts=True)
            returns = dict(zip(ret_labels.tolist(), ret_counts.tolist(), strict=True))
            plab, pcounts = np.unique(planned.label, return_counts=True)
            planned_px = dict(zip(plab.tolist(), pcounts.tolist(), strict=True))
            # pixels of the planned tile that would give a return for sure: in range, below the grazing onset
            p_theta = incidence(planned, camera_rays(optical[:3, :3], grid_u, grid_v))
            sure = (planned.depth >= MIN_RANGE) & (planned.depth <= MAX_RANGE) & (
                p_theta < math.radians(self.model.grazing_onset_deg)
            )
            slab_, scounts = np.unique(planned.label[sure], return_counts=True)
            planned_sure = dict(zip(slab_.tolist(), scounts.tolist(), strict=True))
            scans.append({
                "index": k,
                "stamp": stamp,
                "pose_stamp": round(stamp - POSE_LEAD, 6),
                "bearing_deg": round(math.degrees(base["bearing"]), 2),
                "distance": round(base["distance"], 4),
                "base_pose": {"x": round(base["x"], 5), "y": round(base["y"], 5), "z": round(dz, 5),
                              "roll": round(float(roll), 5), "pitch": round(float(pitch), 5),
                              "yaw": round(base["yaw"], 5)},
                "overhead_pose": {"x": round(base["x"] + ex, 5), "y": round(base["y"] + ey, 5),
                                  "yaw": round(wrap(base["yaw"] + eyaw), 5)},
                "overhead_error": {"position": round(math.hypot(ex, ey), 5), "yaw": round(eyaw, 5)},
                "camera_link_pose": np.round(link, 6).tolist(),
                "camera_optical_pose": np.round(optical, 6).tolist(),
                "robots": robot_records,
                "tile_pixels": {str(t): int(seen.get(t, 0)) for t in self.expected},
                "tile_returns": {str(t): int(returns.get(t, 0)) for t in self.expected},
                "expected_tile_pixels": {str(t): int(planned_px.get(t, 0)) for t in self.expected},
                "expected_tile_returnable": {str(t): int(planned_sure.get(t, 0)) for t in self.expected},
                "returns": int(scan.valid.sum()),
                "label_pixels": {"floor": int(seen.get(FLOOR, 0)), "clutter": int(seen.get(CLUTTER, 0)),
                                 "robot": int(seen.get(ROBOT, 0)), "wall": int(seen.get(WALL, 0)),
                                 "nothing": int(seen.get(NOTHING, 0))},
                "dropouts": scan.dropouts,
                "_cloud": scan.points,
                "_robots": robots,
            })
        return scans


class _LayoutError(Exception):
    """This random layout does not fit; draw another."""


def _centroid_xy(tile: PlacedTile) -> NDArray[np.float64]:
    """Area centroid of the tile's footprint (union of its pieces' hulls)."""
    total, acc = 0.0, np.zeros(2)
    for poly in tile.footprint:
        a = abs(signed_area(poly))
        total += a
        acc += a * poly.mean(axis=0) if len(poly) == 3 else a * _poly_centroid(poly)
    return acc / total if total > 0 else np.vstack(tile.footprint).mean(axis=0)


def _poly_centroid(poly: NDArray[np.float64]) -> NDArray[np.float64]:
    x, y = poly[:, 0], poly[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    c = x * yn - xn * y
    a = c.sum() / 2
    return np.array([((x + xn) * c).sum() / (6 * a), ((y + yn) * c).sum() / (6 * a)])


# --- bag writing -------------------------------------------------------------------------------

def quaternion_yaw(yaw: float) -> tuple[float, float, float, float]:
    return 0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)


def write_bag(folder: Path, scans: list[dict[str, Any]]) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    t = store.types
    cloud_type, pose_type = "sensor_msgs/msg/PointCloud2", "geometry_msgs/msg/PoseStamped"

    def header(stamp: float, frame: str) -> Any:
        sec = math.floor(stamp + 1e-9)
        nanosec = round((stamp - sec) * 1e9)
        return t["std_msgs/msg/Header"](stamp=t["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec),
                                        frame_id=frame)

    def pose_msg(stamp: float, x: float, y: float, yaw: float) -> Any:
        qx, qy, qz, qw = quaternion_yaw(yaw)
        pose = t["geometry_msgs/msg/Pose"](
            position=t["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
            orientation=t["geometry_msgs/msg/Quaternion"](x=qx, y=qy, z=qz, w=qw),
        )
        return t[pose_type](header=header(stamp, "map"), pose=pose)

    fields = [t["sensor_msgs/msg/PointField"](name=n, offset=4 * i, datatype=7, count=1) for i, n in enumerate("xyz")]
    writer = Writer(folder, version=9, storage_plugin=StoragePlugin.MCAP)
    from rosbags.rosbag2 import CompressionFormat, CompressionMode

    writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        cloud_conn = writer.add_connection(CLOUD_TOPIC, cloud_type, typestore=store)
        pose_conn = writer.add_connection(POSE_TOPIC, pose_type, typestore=store)
        robot_conns: dict[str, Any] = {}
        for scan in scans:
            pose_stamp, stamp = scan["pose_stamp"], scan["stamp"]
            ns_pose, ns_cloud = round(pose_stamp * 1e9), round(stamp * 1e9)
            o = scan["overhead_pose"]
            writer.write(pose_conn, ns_pose, store.serialize_cdr(pose_msg(pose_stamp, o["x"], o["y"], o["yaw"]),
                                                                 pose_type))
            for robot in scan["robots"]:
                topic = f"/{robot['name']}/overhead_pose"
                if topic not in robot_conns:
                    robot_conns[topic] = writer.add_connection(topic, pose_type, typestore=store)
                ro = robot["overhead"]
                writer.write(robot_conns[topic], ns_pose,
                             store.serialize_cdr(pose_msg(pose_stamp, ro["x"], ro["y"], ro["yaw"]), pose_type))
            cloud = np.ascontiguousarray(scan["_cloud"], dtype="<f4")
            msg = t[cloud_type](
                header=header(stamp, OPTICAL_FRAME), height=HEIGHT, width=WIDTH, fields=fields, is_bigendian=False,
                point_step=12, row_step=12 * WIDTH, data=np.frombuffer(cloud.tobytes(), dtype=np.uint8),
                is_dense=False,
            )
            writer.write(cloud_conn, ns_cloud, store.serialize_cdr(msg, cloud_type))


# --- one scene ---------------------------------------------------------------------------------

def scene_rng(seed: int, set_name: str, structure_name: str, index: int) -> np.random.Generator:
    """The same scene for the same seed whatever else is generated with it."""
    key = [seed, zlib.crc32(set_name.encode()), zlib.crc32(structure_name.encode()), index]
    return np.random.default_rng(np.random.SeedSequence(key))


def relative(path: Path) -> str:
    try:
        return str(path.resolve().relative_to(REPO))
    except ValueError:
        return str(path.resolve())


def make_scene(structure: Structure, scene_set: SceneSet, seed: int, index: int, model: KinectModel,
               folder: Path, room: float | None = None) -> dict[str, Any]:
    rng = scene_rng(seed, scene_set.name, structure.name, index)
    for _attempt in range(50):
        builder = SceneBuilder(structure, scene_set, rng, model)
        builder.room = room
        try:
            builder.choose_tiles()
            builder.layout()
        except _LayoutError:
            continue
        break
    else:
        raise InputError(f"{structure.path}: could not lay out a scene of set {scene_set.name}")
    scans = builder.scans()
    if folder.exists():
        shutil.rmtree(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    write_bag(folder, scans)
    misplaced_ids = {m["id"] for m in builder.misplaced}
    present = [t for t in builder.expected if t not in builder.removed and t not in misplaced_ids]
    truth = {
        "generator": "tools/independent_scenes.py",
        "seed": seed,
        "scene_index": index,
        "structure": relative(structure.path),
        "structure_name": structure.name,
        "set": scene_set.name,
        "set_description": scene_set.description,
        "nominal_mount": {"xyz": list(scene_set.mount[0]), "rpy": list(scene_set.mount[1])},
        "true_mount": {"xyz": [round(float(v), 6) for v in builder.true_mount[0]],
                       "rpy": [round(float(v), 6) for v in builder.true_mount[1]]},
        "overhead_errors": "at the bounds (5 cm, 10 deg)" if scene_set.bound_errors else "uniform up to 5 cm, 10 deg",
        "kinect": {"width": WIDTH, "height": HEIGHT, "fx": FX, "fy": FY, "cx": CX, "cy": CY,
                   "min_range": MIN_RANGE, "max_range": MAX_RANGE, "projector_baseline": PROJECTOR_BASELINE,
                   **asdict(model)},
        "part_built": builder.part_built,
        "expected": sorted(builder.expected),
        "removed": sorted(builder.removed),
        "misplaced": builder.misplaced,
        "present": sorted(present),
        "tile_types": {str(t): structure.tiles[t].type for t in sorted(structure.tiles)},
        "type_sizes_cm": {n: list(tt.size_cm) for n, tt in structure.types.items()},
        "rests_on": {str(t): sorted(v) for t, v in sorted(structure.rests_on.items())},
        "structure_center": [round(float(v), 5) for v in builder.center],
        "clutter": [c.record() for c in builder.clutter],
        "room_half_size": room,
        "scans": [{k: v for k, v in s.items() if not k.startswith("_")} for s in scans],
    }
    (folder / "truth.json").write_text(json.dumps(truth, indent=1) + "\n", encoding="utf-8")
    return truth


# --- command line ------------------------------------------------------------------------------

def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="independent_scenes.py", description=__doc__.split("\n\n")[2] if __doc__ else None)
    p.add_argument("--out", required=True, help="output folder (one sub-folder per set, one bag per scene)")
    p.add_argument("--seed", required=True, type=int, help="random seed (same seed, same scenes)")
    p.add_argument("--scenes", type=int, default=3, help="scenes per set and structure (default 3)")
    p.add_argument("--structures", default="paper_14,gate_9",
                   help="comma-separated names in config/structures or paths to structure files")
    p.add_argument("--sets", default="all", help=f"'all' or comma-separated of: {', '.join(SCENE_SETS)}")
    p.add_argument("--grazing-onset", type=float, default=70.0, help="deg: returns start to fail here")
    p.add_argument("--grazing-cutoff", type=float, default=77.0, help="deg: no returns beyond")
    p.add_argument("--room", type=float, default=None, metavar="HALF",
                   help="walls of a square room HALF m from the structure's centre (default: none, an open floor; "
                   "for sensitivity checks, not part of the scene sets)")
    return p


def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), _run, argv)


def _run(args: argparse.Namespace) -> int:
    if args.scenes < 1:
        raise InputError(f"--scenes must be at least 1, got {args.scenes}")
    if not 0 <= args.grazing_onset < args.grazing_cutoff <= 90:
        raise InputError("need 0 <= --grazing-onset < --grazing-cutoff <= 90 (deg)")
    names = list(SCENE_SETS) if args.sets.strip() == "all" else [n.strip() for n in args.sets.split(",") if n.strip()]
    unknown = [n for n in names if n not in SCENE_SETS]
    if unknown or not names:
        raise InputError(f"unknown scene set(s) {', '.join(unknown) or '(none given)'}; "
                         f"choose from {', '.join(SCENE_SETS)} or 'all'")
    structures = [load_structure(n.strip()) for n in args.structures.split(",") if n.strip()]
    if not structures:
        raise InputError("--structures names no structure")
    if args.room is not None and not 2.0 <= args.room <= 15.0:
        raise InputError(f"--room must be 2-15 m (the robots stand up to 1.8 m from the centre), got {args.room}")
    model = KinectModel(grazing_onset_deg=args.grazing_onset, grazing_cutoff_deg=args.grazing_cutoff)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"--out {out} exists and is not a folder")
    total = len(names) * len(structures) * args.scenes
    done = 0
    start = time.monotonic()
    for set_name in names:
        for structure in structures:
            for index in range(args.scenes):
                folder = out / set_name / f"{structure.name}_{index:03d}"
                if folder.exists() and not (folder / "truth.json").exists():
                    raise InputError(f"{folder} exists and is not a scene of this generator; not overwriting it")
                t0 = time.monotonic()
                truth = make_scene(structure, SCENE_SETS[set_name], args.seed, index, model, folder, args.room)
                done += 1
                print(f"[{done}/{total}] {set_name} {structure.name} #{index}: expected {len(truth['expected'])}, "
                      f"removed {truth['removed']}, misplaced {[m['id'] for m in truth['misplaced']]} "
                      f"({time.monotonic() - t0:.1f} s)", file=sys.stderr, flush=True)
    print(f"{done} scenes in {out} ({time.monotonic() - start:.0f} s)", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
