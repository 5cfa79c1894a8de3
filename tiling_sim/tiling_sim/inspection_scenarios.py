"""Random inspection scenes as in the paper's experiments (section 3): a structure part-built,
tiles removed (and optionally misplaced), a VI robot looking at it from around, and overhead
localization with the paper's errors (up to 5 cm and 10 degrees).

A scene is the physical world (S_p, with clutter and other robots) plus what the system expects
(S_a, the tiles claimed placed); a view is where the VI robot really is, how its base sits on the
floor, and what the overhead cameras report of it and of the other robots. The Kinect simulator
turns a scene and a view into a cloud. A `Condition` names what the world varies for a set of
scenes (camera mount and its calibration error, distances, the base rocking, localization errors at
their bounds, robots beside the structure or right in front of the camera, grazing dropouts), so
that the inspection is measured per condition (`vi_accuracy`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import networkx as nx
import numpy as np
from numpy.typing import NDArray

from tiling_assembly.contacts import separation
from tiling_assembly.geometry import PlacedTile, rotation_from_rpy, turn_symmetry
from tiling_assembly.polygons import convex_hull_2d, point_in_polygon
from tiling_assembly.structure import Structure
from tiling_sim.faults import SHIFT_RANGE, TURN_RANGE, mistaken_type
from tiling_sim.kinect import ClutterBox, KinectScene, camera_pose

Array = NDArray[np.float64]


def structure_path(name: str) -> Path:
    """A structure file by path, or by name in config/structures (of the working directory, else of
    the source tree this package was built from)."""
    if name.endswith((".yaml", ".yml")):
        return Path(name)
    for root in (Path.cwd(), Path(__file__).resolve().parents[2]):
        candidate = root / "config" / "structures" / f"{name}.yaml"
        if candidate.exists():
            return candidate
    return Path("config") / "structures" / f"{name}.yaml"


# The VI robot's Kinect mount (camera_link in base_link), as in config/vi_node.yaml.
MOUNT_XYZ = (0.08, 0.0, 0.55)
MOUNT_RPY = (0.0, 0.45, 0.0)


@dataclass(frozen=True)
class ViewSettings:
    """Where the VI robot stands and how wrong its overhead pose is."""

    distance: tuple[float, float] = (0.8, 1.5)  # m, base to the structure's centre
    aim_error: float = math.radians(5.0)  # the base does not point exactly at the centre
    base_tilt: float = math.radians(1.5)  # roll and pitch of the base on the floor, up to
    base_height: float = 0.005  # m, base_link height above the floor, up to
    position_error: float = 0.05  # m, overhead position error, up to (uniform over the disc)
    yaw_error: float = math.radians(10.0)  # overhead yaw error, up to (uniform)
    errors_at_bound: bool = False  # True: every overhead error exactly position_error and +-yaw_error
    mount_xyz: tuple[float, float, float] = MOUNT_XYZ  # the true mount (the inspection may be told another)
    mount_rpy: tuple[float, float, float] = MOUNT_RPY


DEFAULT_VIEW = ViewSettings()


@dataclass(frozen=True)
class View:
    """One VI robot pose: the truth, and what the overhead cameras say."""

    base: tuple[float, float, float]  # true x, y, yaw of base_link
    tilt: tuple[float, float, float]  # true base z, roll, pitch
    overhead: tuple[float, float, float]  # reported x, y, yaw
    settings: ViewSettings = DEFAULT_VIEW
    robots: tuple[tuple[float, float, float], ...] = ()  # reported x, y, yaw of the other robots

    @cached_property
    def camera(self) -> Array:
        """True 4x4 pose of the optical frame in the map."""
        z, roll, pitch = self.tilt
        return camera_pose(*self.base, self.settings.mount_xyz, self.settings.mount_rpy, z, roll, pitch)

    def to_dict(self) -> dict[str, object]:
        return {
            "base": list(self.base),
            "tilt": list(self.tilt),
            "overhead": list(self.overhead),
            "camera": np.asarray(self.camera).round(6).tolist(),
            "robots": [list(r) for r in self.robots],
        }


@dataclass
class Scene:
    """The physical world and what the system expects of it."""

    structure: Structure
    expected: tuple[int, ...]  # S_a: tiles claimed placed
    removed: tuple[int, ...]  # claimed placed but physically gone
    misplaced: dict[int, PlacedTile] = field(default_factory=dict)  # claimed placed, physically elsewhere
    clutter: tuple[ClutterBox | PlacedTile, ...] = ()
    robots: tuple[ClutterBox, ...] = ()  # other robots: the overhead cameras report these

    @property
    def present(self) -> tuple[int, ...]:
        """Tiles of S_a physically at their place."""
        return tuple(i for i in self.expected if i not in self.removed and i not in self.misplaced)

    @cached_property
    def kinect_scene(self) -> KinectScene:
        tiles = [self.structure.tiles[i] for i in self.present] + list(self.misplaced.values())
        return KinectScene(tiles, (*self.clutter, *self.robots))

    @property
    def unreported(self) -> tuple[ClutterBox, ...]:
        """The boxes on the floor no overhead camera reports (the VI robot's laser sees them)."""
        return tuple(item for item in self.clutter if isinstance(item, ClutterBox))

    @property
    def centre(self) -> Array:
        low, high = self.structure.subset(self.expected).bounds
        return 0.5 * (low + high)

    def truth(self) -> dict[str, object]:
        return {
            "expected": list(self.expected),
            "removed": list(self.removed),
            "misplaced": sorted(self.misplaced),
            "present": list(self.present),
        }


def build_prefix(structure: Structure, rng: np.random.Generator, count: int) -> tuple[int, ...]:
    """`count` tiles that could have been placed first: a random order respecting supports."""
    graph = structure.precedence.copy()
    order: list[int] = []
    while graph.number_of_nodes() and len(order) < count:
        ready = sorted(n for n in graph.nodes if graph.in_degree(n) == 0)
        pick = int(rng.choice(ready))
        order.append(pick)
        graph.remove_node(pick)
    return tuple(sorted(order))


def _resting_on(structure: Structure, tile: int, among: Iterable[int]) -> set[int]:
    """Tiles of `among` that rest, directly or not, on `tile`."""
    among = set(among)
    above = nx.descendants(structure.precedence, tile)
    return {t for t in above if t in among}


def removable(structure: Structure, expected: Iterable[int], gone: Iterable[int] = ()) -> list[int]:
    """Tiles a hand could lift off without disturbing the rest (nothing still there rests on them)."""
    still = set(expected) - set(gone)
    return sorted(t for t in still if not _resting_on(structure, t, still))


def remove_tiles(
    structure: Structure, expected: Iterable[int], rng: np.random.Generator, count: int
) -> tuple[int, ...]:
    """Remove `count` random tiles, each one that nothing left rests on (as in the paper's trials)."""
    gone: list[int] = []
    for _ in range(count):
        options = removable(structure, expected, gone)
        if not options:
            break
        gone.append(int(rng.choice(options)))
    return tuple(sorted(gone))


def outline_moved(planned: PlacedTile, placed: PlacedTile) -> float:
    """How far (m) the footprint of `placed` lies from that of `planned`, at worst, either way: what
    a camera looking down has to resolve to tell the two apart. A turn of a symmetric tile moves
    little (an octagon turned 22 degrees: 4 mm), a shift moves every corner by the shift."""
    ours, theirs = _footprints(planned), _footprints(placed)
    return max(
        max(_distance_to_pieces(corner, ours) for piece in theirs for corner in piece),
        max(_distance_to_pieces(corner, theirs) for piece in ours for corner in piece),
    )


def _footprints(tile: PlacedTile) -> list[Array]:
    """The tile's convex pieces seen from above."""
    return [convex_hull_2d(piece[:, :2]) for piece in tile.pieces]


def _distance_to_pieces(point: Array, pieces: list[Array]) -> float:
    return min(_distance_to_convex(point, piece) for piece in pieces)


def _distance_to_convex(point: Array, polygon: Array) -> float:
    """Distance from `point` to the convex `polygon` (0 inside)."""
    if point_in_polygon(point, polygon, 0.0):
        return 0.0
    edges = np.roll(polygon, -1, axis=0) - polygon
    to_point = point - polygon
    along = np.clip(np.einsum("ij,ij->i", to_point, edges) / np.einsum("ij,ij->i", edges, edges), 0.0, 1.0)
    return float(np.min(np.linalg.norm(to_point - along[:, None] * edges, axis=1)))


def misplace_tile(
    structure: Structure,
    tile_id: int,
    others: Iterable[int],
    rng: np.random.Generator,
    shift: tuple[float, float] = SHIFT_RANGE,
    turn: tuple[float, float] = TURN_RANGE,
    kind: str = "shift",
    attempts: int = 50,
) -> PlacedTile | None:
    """The tile shifted (by shift[0]..shift[1] m), turned (by turn[0]..turn[1] rad about its centroid)
    or, `kind` "wrong_type", a tile of the type a robot takes for it by mistake in its place, without
    overlapping the `others`; None if no such pose (or no such type) was found."""
    tile = structure.tiles[tile_id]
    neighbours = [structure.tiles[i] for i in others if i != tile_id]
    if kind == "wrong_type":
        other = mistaken_type(structure, tile.type_name)
        if other is None:
            return None
        swapped = PlacedTile(tile.tile_id, other, structure.tile_types[other].shape, tile.rotation, tile.position)
        return swapped if all(separation(swapped, n) > -1e-4 for n in neighbours) else None
    for _ in range(attempts):
        if kind == "shift":
            angle = rng.uniform(0, 2 * math.pi)
            distance = rng.uniform(*shift)
            rotation = tile.rotation
            position = tile.position + distance * np.array([math.cos(angle), math.sin(angle), 0.0])
        else:
            largest = min(turn[1], math.pi / turn_symmetry(tile))  # further would turn it back towards its place
            turn_by = rng.uniform(turn[0], largest) * rng.choice([-1.0, 1.0])
            spin = rotation_from_rpy(0.0, 0.0, turn_by)
            rotation = spin @ tile.rotation
            position = spin @ (tile.position - tile.centroid) + tile.centroid
        moved = PlacedTile(tile.tile_id, tile.type_name, tile.shape, rotation, position)
        if all(separation(moved, other) > -1e-4 for other in neighbours):
            return moved
    return None


def random_scene(
    structure: Structure,
    rng: np.random.Generator,
    removals: tuple[int, int] = (1, 3),
    partial: float = 0.3,
    clutter: float = 0.3,
    misplacements: int = 0,
    misplace_kind: str | None = None,
) -> Scene:
    """A part-built structure (with probability `partial`), some tiles removed, maybe clutter."""
    n = len(structure)
    count = n if rng.random() >= partial else int(rng.integers(max(2, n // 2), n + 1))
    expected = build_prefix(structure, rng, count)
    removed = remove_tiles(structure, expected, rng, int(rng.integers(removals[0], removals[1] + 1)))
    misplaced: dict[int, PlacedTile] = {}
    for _ in range(misplacements):
        options = [t for t in removable(structure, expected, removed) if t not in misplaced]
        if not options:
            break
        pick = int(rng.choice(options))
        kind = misplace_kind or str(rng.choice(["shift", "turn"]))
        others = [t for t in expected if t not in removed and t != pick]
        moved = misplace_tile(structure, pick, others, rng, kind=kind)
        if moved is not None:
            misplaced[pick] = moved
    items: list[ClutterBox | PlacedTile] = []
    if rng.random() < clutter:
        items.extend(random_clutter(structure, rng))
    return Scene(structure, expected, removed, misplaced, tuple(items))


def random_clutter(structure: Structure, rng: np.random.Generator) -> list[ClutterBox | PlacedTile]:
    """Another robot beside the structure and a loose tile on the floor."""
    low, high = structure.bounds
    centre = 0.5 * (low + high)
    angle = rng.uniform(0, 2 * math.pi)
    reach = 0.5 * float(np.linalg.norm(high[:2] - low[:2])) + rng.uniform(0.25, 0.45)
    robot = ClutterBox(
        (centre[0] + reach * math.cos(angle), centre[1] + reach * math.sin(angle), 0.15),
        (0.32, 0.32, 0.30),
        rng.uniform(0, math.pi),
    )
    any_tile = structure.tiles[int(rng.choice(structure.tile_ids))]
    angle = rng.uniform(0, 2 * math.pi)
    reach = 0.5 * float(np.linalg.norm(high[:2] - low[:2])) + rng.uniform(0.08, 0.2)
    loose = PlacedTile(
        -1,
        any_tile.type_name,
        any_tile.shape,
        rotation_from_rpy(0.0, 0.0, rng.uniform(0, math.pi)),
        np.array([centre[0] + reach * math.cos(angle), centre[1] + reach * math.sin(angle), 0.0]),
    )
    return [robot, loose]


def view_from(
    centre: Array,
    bearing: float,
    distance: float,
    rng: np.random.Generator,
    settings: ViewSettings = DEFAULT_VIEW,
    robots: tuple[ClutterBox, ...] = (),
    obstacles: tuple[ClutterBox, ...] = (),
) -> View:
    """The VI robot at `distance` from `centre` on `bearing`, facing it, with random errors; the
    overhead cameras also report the other `robots`, with errors of the same kind. The VI robot does
    not stand on another robot, nor on the `obstacles` no overhead camera reports (a box on the
    floor: its laser sees it): it backs off along the bearing until it is clear of them."""
    solid = (*robots, *obstacles)
    for _ in range(100):
        x = centre[0] + distance * math.cos(bearing)
        y = centre[1] + distance * math.sin(bearing)
        if all(_clear_of(r, _outline(_square((x, y), VI_BASE_RADIUS)), VI_CLEARANCE) for r in solid):
            break
        distance += 0.05
    yaw = bearing + math.pi + rng.uniform(-settings.aim_error, settings.aim_error)
    tilt = (
        rng.uniform(-settings.base_height, settings.base_height),
        rng.uniform(-settings.base_tilt, settings.base_tilt),
        rng.uniform(-settings.base_tilt, settings.base_tilt),
    )
    reported = tuple(_overhead((r.center[0], r.center[1], r.yaw), rng, settings) for r in robots)
    return View((x, y, _wrap(yaw)), tilt, _overhead((x, y, yaw), rng, settings), settings, reported)


def _overhead(truth: tuple[float, float, float], rng: np.random.Generator, settings: ViewSettings) -> tuple[
    float, float, float
]:
    """What the overhead cameras report of a base at `truth` (x, y, yaw)."""
    error_angle = rng.uniform(0, 2 * math.pi)
    if settings.errors_at_bound:
        error = settings.position_error
        turn = settings.yaw_error * float(rng.choice([-1.0, 1.0]))
    else:
        error = settings.position_error * math.sqrt(rng.random())
        turn = rng.uniform(-settings.yaw_error, settings.yaw_error)
    x, y, yaw = truth
    return x + error * math.cos(error_angle), y + error * math.sin(error_angle), _wrap(yaw + turn)


def random_view(
    centre: Array, rng: np.random.Generator, settings: ViewSettings = DEFAULT_VIEW, robots: tuple[ClutterBox, ...] = (),
    obstacles: tuple[ClutterBox, ...] = (),
) -> View:
    bearing, distance = rng.uniform(0, 2 * math.pi), rng.uniform(*settings.distance)
    return view_from(centre, bearing, distance, rng, settings, robots, obstacles)


def ring_of_views(
    centre: Array,
    rng: np.random.Generator,
    count: int = 12,
    distance: float = 1.1,
    settings: ViewSettings = DEFAULT_VIEW,
    robots: tuple[ClutterBox, ...] = (),
    obstacles: tuple[ClutterBox, ...] = (),
) -> list[View]:
    """Candidate viewpoints evenly around the structure (for next-viewpoint choice)."""
    start = rng.uniform(0, 2 * math.pi)
    return [
        view_from(centre, start + 2 * math.pi * k / count, distance, rng, settings, robots, obstacles)
        for k in range(count)
    ]


# -- conditions ---------------------------------------------------------------------------------------
ROBOT_BOX = (0.33, 0.33, 0.35)  # m, an assembly robot as the world simulates it
VI_BASE_RADIUS = 0.17  # m, the VI robot's round base (an iRobot Create)
VI_CLEARANCE = 0.25  # m the VI robot keeps from other robots (no one parks a camera against a robot)
LOW_MOUNT = ((0.10, 0.0, 0.28), (0.0, 0.20, 0.0))  # a camera low on the base, pitched a little down


@dataclass(frozen=True)
class Condition:
    """What the world varies for a set of scenes."""

    name: str
    description: str
    mount: tuple[tuple[float, float, float], tuple[float, float, float]] = (MOUNT_XYZ, MOUNT_RPY)  # nominal
    mount_error: tuple[float, float] = (0.0, 0.0)  # true mount off the nominal one by up to (m, rad) per axis
    distance: tuple[float, float] = (0.8, 1.5)  # m, VI robot to the structure's centre
    errors_at_bound: bool = False  # overhead errors exactly 5 cm and 10 deg (else uniform up to those)
    rocking: tuple[float, float] = (0.005, math.radians(1.5))  # base height (m) and roll/pitch (rad), per scan
    robots_beside: tuple[int, int] = (0, 0)  # robots standing 3-15 cm from the structure's tiles
    robot_near_camera: bool = False  # a robot 0.2-0.45 m in front of the camera, off to one side
    clutter: float = 0.3  # chance of a box and a loose tile on the floor nearby
    grazing_start: tuple[float, float] = (math.radians(78.0), math.radians(78.0))  # dropout onset, rad

    def view_settings(self, rng: np.random.Generator) -> ViewSettings:
        """The views of one scene: the true mount drawn about the nominal one."""
        xyz, rpy = self.mount
        error_xyz, error_rpy = self.mount_error
        return ViewSettings(
            distance=self.distance,
            base_tilt=self.rocking[1],
            base_height=self.rocking[0],
            errors_at_bound=self.errors_at_bound,
            mount_xyz=tuple(float(v + rng.uniform(-error_xyz, error_xyz)) for v in xyz),  # type: ignore[arg-type]
            mount_rpy=tuple(float(v + rng.uniform(-error_rpy, error_rpy)) for v in rpy),  # type: ignore[arg-type]
        )


_WORLD = {
    "mount_error": (0.005, math.radians(1.0)),
    "errors_at_bound": True,
    "rocking": (0.01, math.radians(1.5)),
    "robots_beside": (1, 2),
    "clutter": 1.0,
    "grazing_start": (math.radians(70.0), math.radians(78.0)),
}
CONDITIONS = {
    c.name: c
    for c in (
        Condition("paper", "high mount, errors up to the paper's bounds, some clutter"),
        Condition(
            "world",
            "high mount off by 5 mm / 1 deg, errors at the bounds, base rocking 1 cm / 1.5 deg, 1-2 robots "
            "beside the structure, clutter, grazing dropouts from 70-78 deg",
            **_WORLD,  # type: ignore[arg-type]
        ),
        Condition("low", "as world, camera low (0.28 m, pitched 0.20 rad)", mount=LOW_MOUNT, **_WORLD),  # type: ignore[arg-type]
        Condition(
            "low_close", "as low, 0.6-0.9 m from the structure", mount=LOW_MOUNT, distance=(0.6, 0.9), **_WORLD  # type: ignore[arg-type]
        ),
        Condition(
            "robot_near",
            "as world, plus a robot 0.2-0.45 m in front of the camera",
            robot_near_camera=True,
            **_WORLD,  # type: ignore[arg-type]
        ),
    )
}


def robots_beside(structure: Structure, expected: Iterable[int], rng: np.random.Generator, count: int) -> tuple[
    ClutterBox, ...
]:
    """`count` robot boxes standing 3-15 cm from the nearest tile of `expected`, clear of every tile."""
    tiles = [structure.tiles[t] for t in expected] or list(structure.tiles.values())
    corners = np.vstack([_outline(t.vertices[:, :2]) for t in tiles])
    centre = corners.mean(axis=0)
    robots: list[ClutterBox] = []
    for _ in range(count):
        for _attempt in range(50):
            bearing = rng.uniform(0, 2 * math.pi)
            yaw = rng.uniform(0, math.pi)
            gap = rng.uniform(0.03, 0.15)
            direction = np.array([math.cos(bearing), math.sin(bearing)])
            # walk out from the centre until the box keeps `gap` from every tile corner and from the other robots
            for reach in np.arange(0.05, 1.5, 0.01):
                xy = centre + reach * direction
                box = ClutterBox((float(xy[0]), float(xy[1]), ROBOT_BOX[2] / 2), ROBOT_BOX, yaw)
                if _clear_of(box, corners, gap) and all(_clear_of(box, _corners(r), 0.05) for r in robots):
                    robots.append(box)
                    break
            else:
                continue
            break
    return tuple(robots)


def robot_in_front(view: View, rng: np.random.Generator) -> ClutterBox:
    """A robot 0.2-0.45 m in front of the VI robot's camera, off to one side: nearer than the
    Kinect's range, it blanks part of the image and shades more with the projector."""
    x, y, yaw = view.base
    ahead = view.settings.mount_xyz[0] + rng.uniform(0.2, 0.45) + ROBOT_BOX[0] / 2
    side = rng.choice([-1.0, 1.0]) * rng.uniform(0.15, 0.3)
    cx = x + ahead * math.cos(yaw) - side * math.sin(yaw)
    cy = y + ahead * math.sin(yaw) + side * math.cos(yaw)
    return ClutterBox((cx, cy, ROBOT_BOX[2] / 2), ROBOT_BOX, float(rng.uniform(0, math.pi)))


def _corners(box: ClutterBox) -> Array:
    vertices, _ = box.mesh()
    return _outline(vertices[:4, :2][[0, 1, 3, 2]])


def _square(centre: tuple[float, float], half: float) -> Array:
    x, y = centre
    return np.array([[x - half, y - half], [x + half, y - half], [x + half, y + half], [x - half, y + half]])


def _outline(points: Array, step: float = 0.01) -> Array:
    """Points every `step` (m) along the closed polygon through the convex hull of `points`."""
    hull = convex_hull_2d(points)
    samples = [hull]
    for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True):
        n = max(1, int(np.linalg.norm(b - a) / step))
        samples.append(a + np.linspace(0, 1, n, endpoint=False)[:, None] * (b - a))
    return np.vstack(samples)


def _clear_of(box: ClutterBox, points: Array, gap: float) -> bool:
    """Whether every point lies at least `gap` outside the box's footprint."""
    c, s = math.cos(box.yaw), math.sin(box.yaw)
    relative = points - np.asarray(box.center[:2])
    along = np.abs(c * relative[:, 0] + s * relative[:, 1]) - box.size[0] / 2
    across = np.abs(-s * relative[:, 0] + c * relative[:, 1]) - box.size[1] / 2
    outside = np.hypot(np.maximum(along, 0.0), np.maximum(across, 0.0))
    return bool(np.all((outside >= gap) & ((along > 0) | (across > 0))))


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi
