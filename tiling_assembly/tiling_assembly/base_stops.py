"""Where a robot's base stops beside the structure to place a tile (paper section 3.1: the robot
drives from the parts cache to the structure and places the tile with its arm).

The base stops `approach_distance` (the arm's reach) off the tile's centre, on the side of the
tile's parts cache. Where its footprint (a box of `base_size`, kept `clearance` from every tile)
would stand on the structure, it stops at the nearest spot around the tile where it stands clear:
headings every 5 degrees round the tile (a turn away from the cache's side costs 2 cm per radian),
the first clear distance on each. That is the rule of the simulated robots
(`tiling_sim.robot_motion.approach_point`); here it is worked out for every tile at once, on a
grid of the structure's footprint (1 cm cells up to 2 m x 2 m, coarser beyond), marching out from
the nearest clear cell (an exact distance transform at the tiles' centres), once per spot and
cache (tiles stacked on one spot share their stop): about 0.1 s for a 10,000-tile pyramid. On
pyramid_91 and arcade_294 the drives from the caches to the stops found both ways differ by 2 cm
at most (`tests/sim/test_base_stops.py`).

Every tile of the structure stands where no base can, built yet or not: a plan does not know which
tiles will be there when a robot comes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.structure import Structure

Array = NDArray[np.float64]

TURNS = np.radians(5.0 * np.arange(-35, 37))  # headings tried round a tile, from the cache's side
TURN_PENALTY = 0.02  # m per rad: of two stops equally near the tile, the one nearer the cache side wins
MAX_CELLS = 40_000  # 1 cm cells up to 2 m x 2 m; bigger footprints get coarser ones (10,000 tiles: 2 cm)


@dataclass(frozen=True)
class BaseGeometry:
    """The base of an assembly robot, as far as where it can stop matters (defaults: `TimeModel`)."""

    approach_distance: float  # m from a tile's centre to where the base stops (the arm's reach)
    base_size: tuple[float, float]  # m, x and y size of the base's footprint (a box)
    clearance: float  # m the base keeps from every tile of the structure


@dataclass(frozen=True)
class _Grid:
    """Cells a base's centre cannot stand on (True), `cell` m wide, cell (0, 0) starting at `origin`."""

    blocked: NDArray[np.bool_]
    origin: Array
    cell: float

    def clear(self, points: Array) -> NDArray[np.bool_]:
        """For (..., 2) points: whether a base centred there stands clear (off the grid: clear, as
        the ring of cells round its edge is)."""
        index = np.floor((points - self.origin) / self.cell).astype(np.int64)
        rows = np.clip(index[..., 0], 0, self.blocked.shape[0] - 1)
        columns = np.clip(index[..., 1], 0, self.blocked.shape[1] - 1)
        return ~self.blocked[rows, columns]

    def nearest_clear(self, points: Array) -> Array:
        """(n, 2) the centre of the clear cell nearest to each point's cell (exact Euclidean distance
        transform at the query cells: per column the nearest clear row, then the best column)."""
        rows, columns = self.blocked.shape
        index = np.clip(np.floor((points - self.origin) / self.cell).astype(np.int64), 0, [rows - 1, columns - 1])
        row_index = np.arange(rows)[:, None]
        far = 4 * (rows + columns)
        below = np.maximum.accumulate(np.where(self.blocked, -far, row_index), axis=0)  # last clear row <= i
        above = np.minimum.accumulate(np.where(self.blocked, far, row_index)[::-1], axis=0)[::-1]  # first >= i
        i = index[:, 0:1]
        down, up = below[index[:, 0]], above[index[:, 0]]  # (n, columns)
        row = np.where(i - down <= up - i, down, up)
        squared = (row - i) ** 2 + (np.arange(columns)[None, :] - index[:, 1:2]) ** 2
        best = np.argmin(squared, axis=1)
        cells = np.column_stack([row[np.arange(len(points)), best], best])
        return self.origin + (cells + 0.5) * self.cell


def approach_stops(structure: Structure, towards: Array, geometry: BaseGeometry) -> Array:
    """(n, 2) where the base stops to place each tile of `structure` (in id order), coming from
    `towards` ((n, 2): the tile's parts cache)."""
    ids = list(structure.tiles)
    if not ids:
        return np.zeros((0, 2))
    centres = np.array([structure.tiles[t].centroid[:2] for t in ids], dtype=float)
    # a 10,000-tile pyramid has 1,861 different spots
    cases, case_of = np.unique(np.column_stack([centres, towards]), axis=0, return_inverse=True)
    bare = max(geometry.base_size) <= 0.0 and geometry.clearance <= 0.0
    grid = None if bare else _footprint_grid(structure, geometry)
    return _stops_on(cases[:, :2], cases[:, 2:], grid, geometry)[case_of.reshape(-1)]


def _stops_on(centres: Array, towards: Array, grid: _Grid | None, geometry: BaseGeometry) -> Array:
    """An arm's reach towards the cache where the base stands clear there; else the first clear
    distance on every heading round the tile, marching out from where the nearest clear cell is (no
    heading clears sooner), until a heading is clear whose cost no later one can beat."""
    away = towards - centres
    heading = np.arctan2(away[:, 1], away[:, 0])
    stops = centres + geometry.approach_distance * np.column_stack([np.cos(heading), np.sin(heading)])
    if grid is None:
        return stops
    boxed_in = np.flatnonzero(~grid.clear(stops))
    centres = centres[boxed_in]
    nearest = np.linalg.norm(grid.nearest_clear(centres) - centres, axis=1)
    start = np.maximum(geometry.approach_distance, nearest - grid.cell)
    headings = heading[boxed_in, None] + TURNS[None, :]
    directions = np.stack([np.cos(headings), np.sin(headings)], axis=-1)  # (tiles, turns, 2)
    first_clear = np.full(headings.shape, np.inf)
    penalty = TURN_PENALTY * np.abs(TURNS)[None, :]
    rows = np.arange(len(boxed_in))
    for step in range(int(np.hypot(*grid.blocked.shape)) + 2):  # off the grid everything is clear
        distance = start[rows, None] + step * grid.cell
        clear = grid.clear(centres[rows, None, :] + distance[..., None] * directions[rows])
        first_clear[rows] = np.where(clear & np.isinf(first_clear[rows]), distance, first_clear[rows])
        # a heading first clear further out cannot beat one clear here (the penalty is below a step)
        settled = (first_clear[rows] + penalty).min(axis=1) <= distance[:, 0] + grid.cell
        rows = rows[~settled]
        if not rows.size:
            break
    best = np.argmin(first_clear + penalty, axis=1)
    chosen = np.arange(len(boxed_in))
    stops[boxed_in] = centres + first_clear[chosen, best, None] * directions[chosen, best]
    return stops


def _footprint_grid(structure: Structure, geometry: BaseGeometry) -> _Grid:
    """Cells whose centre is inside some tile's footprint, grown by the base's half size and
    clearance: where a base's centre cannot stand."""
    low, high = structure.bounds
    half = np.array(geometry.base_size, dtype=float) / 2.0 + geometry.clearance
    area = float(np.prod(high[:2] - low[:2] + 2.0 * half))
    cell = max(0.01, math.sqrt(area / MAX_CELLS))
    grow = np.round(half / cell).astype(int)
    margin = (grow + 2) * cell  # a ring of clear cells all round
    origin = low[:2] - margin
    shape = tuple(int(v) for v in np.ceil((high[:2] + margin - origin) / cell))
    occupied = np.zeros(shape, dtype=bool)
    for outline, positions in _outlines(structure):
        _fill(occupied, outline, np.unique(positions, axis=0), origin, cell)  # stacked tiles cover one spot
    return _Grid(_grown(occupied, int(grow[0]), int(grow[1])), origin, cell)


def _outlines(structure: Structure) -> list[tuple[Array, Array]]:
    """Tiles of one shape turned the same way share an outline (relative to their position)."""
    groups: dict[tuple[int, bytes], list[int]] = {}
    for tile_id, tile in structure.tiles.items():
        groups.setdefault((id(tile.shape), tile.rotation.tobytes()), []).append(tile_id)
    result = []
    for members in groups.values():
        first = structure.tiles[members[0]]
        outline = convex_hull_2d((first.shape.vertices @ first.rotation.T)[:, :2])
        result.append((outline, np.array([structure.tiles[t].position[:2] for t in members], dtype=float)))
    return result


def _fill(occupied: NDArray[np.bool_], outline: Array, positions: Array, origin: Array, cell: float) -> None:
    """Mark the cells whose centre lies inside `outline` placed at each of `positions`."""
    start = np.floor((positions + outline.min(axis=0) - origin) / cell).astype(np.int64)
    size = np.ceil((outline.max(axis=0) - outline.min(axis=0)) / cell).astype(np.int64) + 2
    offsets = np.stack(np.meshgrid(np.arange(size[0]), np.arange(size[1]), indexing="ij"), axis=-1).reshape(-1, 2)
    cells = start[:, None, :] + offsets[None, :, :]  # (tiles, window, 2)
    centres = origin + (cells + 0.5) * cell - positions[:, None, :]
    edges = np.roll(outline, -1, axis=0) - outline
    relative = centres[..., None, :] - outline  # (tiles, window, corners, 2)
    cross = edges[:, 0] * relative[..., 1] - edges[:, 1] * relative[..., 0]
    inside = (cross >= -1e-12).all(axis=-1) if len(outline) >= 3 else np.zeros(cells.shape[:2], dtype=bool)
    hit = cells[inside]
    hit = hit[(hit >= 0).all(axis=1) & (hit[:, 0] < occupied.shape[0]) & (hit[:, 1] < occupied.shape[1])]
    occupied[hit[:, 0], hit[:, 1]] = True


def _grown(occupied: NDArray[np.bool_], grow_x: int, grow_y: int) -> NDArray[np.bool_]:
    """Cells with an occupied cell within `grow_x` x `grow_y` cells of them (a box dilation by
    summed-area table)."""
    table = np.zeros((occupied.shape[0] + 1, occupied.shape[1] + 1), dtype=np.int64)
    table[1:, 1:] = occupied.cumsum(axis=0).cumsum(axis=1)
    rows = np.arange(occupied.shape[0])
    columns = np.arange(occupied.shape[1])
    r0, r1 = np.clip(rows - grow_x, 0, occupied.shape[0]), np.clip(rows + grow_x + 1, 0, occupied.shape[0])
    c0, c1 = np.clip(columns - grow_y, 0, occupied.shape[1]), np.clip(columns + grow_y + 1, 0, occupied.shape[1])
    total = table[r1][:, c1] - table[r0][:, c1] - table[r1][:, c0] + table[r0][:, c0]
    return total > 0
