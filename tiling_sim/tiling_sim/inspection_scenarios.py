"""Random inspection scenes as in the paper's experiments (section 3): a structure part-built,
tiles removed (and optionally misplaced), a VI robot looking at it from around, and overhead
localization with the paper's errors (up to 5 cm and 10 degrees).

A scene is the physical world (S_p, with clutter) plus what the system expects (S_a, the tiles
claimed placed); a view is where the VI robot really is, how its base sits on the floor, and what
the overhead cameras report. The Kinect simulator turns a scene and a view into a cloud.
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
from tiling_assembly.geometry import PlacedTile, rotation_from_rpy
from tiling_assembly.structure import Structure
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
    mount_xyz: tuple[float, float, float] = MOUNT_XYZ
    mount_rpy: tuple[float, float, float] = MOUNT_RPY


DEFAULT_VIEW = ViewSettings()


@dataclass(frozen=True)
class View:
    """One VI robot pose: the truth, and what the overhead cameras say."""

    base: tuple[float, float, float]  # true x, y, yaw of base_link
    tilt: tuple[float, float, float]  # true base z, roll, pitch
    overhead: tuple[float, float, float]  # reported x, y, yaw
    settings: ViewSettings = DEFAULT_VIEW

    @cached_property
    def camera(self) -> Array:
        """True 4x4 pose of the optical frame in the map."""
        z, roll, pitch = self.tilt
        return camera_pose(*self.base, self.settings.mount_xyz, self.settings.mount_rpy, z, roll, pitch)

    def to_dict(self) -> dict[str, list[float]]:
        return {
            "base": list(self.base),
            "tilt": list(self.tilt),
            "overhead": list(self.overhead),
            "camera": np.asarray(self.camera).round(6).tolist(),
        }


@dataclass
class Scene:
    """The physical world and what the system expects of it."""

    structure: Structure
    expected: tuple[int, ...]  # S_a: tiles claimed placed
    removed: tuple[int, ...]  # claimed placed but physically gone
    misplaced: dict[int, PlacedTile] = field(default_factory=dict)  # claimed placed, physically elsewhere
    clutter: tuple[ClutterBox | PlacedTile, ...] = ()

    @property
    def present(self) -> tuple[int, ...]:
        """Tiles of S_a physically at their place."""
        return tuple(i for i in self.expected if i not in self.removed and i not in self.misplaced)

    @cached_property
    def kinect_scene(self) -> KinectScene:
        tiles = [self.structure.tiles[i] for i in self.present] + list(self.misplaced.values())
        return KinectScene(tiles, self.clutter)

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


def misplace_tile(
    structure: Structure,
    tile_id: int,
    others: Iterable[int],
    rng: np.random.Generator,
    shift: tuple[float, float] = (0.02, 0.03),
    turn: tuple[float, float] = (math.radians(15), math.radians(30)),
    kind: str = "shift",
    attempts: int = 50,
) -> PlacedTile | None:
    """The tile shifted (by shift[0]..shift[1] m) or turned (by turn[0]..turn[1] rad about its centroid)
    without overlapping the `others`; None if no such pose was found."""
    tile = structure.tiles[tile_id]
    neighbours = [structure.tiles[i] for i in others if i != tile_id]
    for _ in range(attempts):
        if kind == "shift":
            angle = rng.uniform(0, 2 * math.pi)
            distance = rng.uniform(*shift)
            rotation = tile.rotation
            position = tile.position + distance * np.array([math.cos(angle), math.sin(angle), 0.0])
        else:
            turn_by = rng.uniform(*turn) * rng.choice([-1.0, 1.0])
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
) -> View:
    """The VI robot at `distance` from `centre` on `bearing`, facing it, with random errors."""
    x = centre[0] + distance * math.cos(bearing)
    y = centre[1] + distance * math.sin(bearing)
    yaw = bearing + math.pi + rng.uniform(-settings.aim_error, settings.aim_error)
    tilt = (
        rng.uniform(-settings.base_height, settings.base_height),
        rng.uniform(-settings.base_tilt, settings.base_tilt),
        rng.uniform(-settings.base_tilt, settings.base_tilt),
    )
    error_angle = rng.uniform(0, 2 * math.pi)
    if settings.errors_at_bound:
        error = settings.position_error
        turn = settings.yaw_error * float(rng.choice([-1.0, 1.0]))
    else:
        error = settings.position_error * math.sqrt(rng.random())
        turn = rng.uniform(-settings.yaw_error, settings.yaw_error)
    overhead = (x + error * math.cos(error_angle), y + error * math.sin(error_angle), yaw + turn)
    return View((x, y, _wrap(yaw)), tilt, (overhead[0], overhead[1], _wrap(overhead[2])), settings)


def random_view(centre: Array, rng: np.random.Generator, settings: ViewSettings = DEFAULT_VIEW) -> View:
    return view_from(centre, rng.uniform(0, 2 * math.pi), rng.uniform(*settings.distance), rng, settings)


def ring_of_views(
    centre: Array,
    rng: np.random.Generator,
    count: int = 12,
    distance: float = 1.1,
    settings: ViewSettings = DEFAULT_VIEW,
) -> list[View]:
    """Candidate viewpoints evenly around the structure (for next-viewpoint choice)."""
    start = rng.uniform(0, 2 * math.pi)
    return [view_from(centre, start + 2 * math.pi * k / count, distance, rng, settings) for k in range(count)]


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi
