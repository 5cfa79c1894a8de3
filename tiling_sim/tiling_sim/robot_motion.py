"""How long the simulated robots take (paper section 3.1: an M3 robot drives to the parts cache of
the tile's type, finds and picks the tile, drives to the structure and places it).

A placement is a sequence of timed phases from the robot's current position; durations follow
distance and speed, plus fixed pick and place times, all from `config/tiling_sim.yaml`. The robot
stands off the tile by `approach_distance` (the arm's reach) on the side facing its cache, or further
out on that side when its base would otherwise stand on other tiles of the structure. It stands off
the parts cache by as much, on the side it comes from (the real M3 stops `pick_standoff` from it):
several robots can pick from one cache at once, from different sides (`standing_room`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

Point2 = tuple[float, float]
Polygon = NDArray[np.float64]  # (N, 2) convex, counter-clockwise


@dataclass(frozen=True)
class MotionModel:
    drive_speed: float = 0.15  # m/s
    turn_speed: float = 1.0  # rad/s
    locate_time: float = 2.0  # s, laser scan at the cache
    pick_time: float = 6.0  # s, arm down, grasp, up
    place_time: float = 10.0  # s, arm out, release, back
    retreat_time: float = 2.0  # s, back off from the structure
    approach_distance: float = 0.25  # m from the tile's centre to where the base stops
    base_size: Point2 = (0.0, 0.0)  # m, x and y size of the base's footprint (an axis-aligned box)
    base_clearance: float = 0.03  # m the base keeps from every tile of the structure

    def __post_init__(self) -> None:
        for name in ("drive_speed", "turn_speed"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive")


@dataclass(frozen=True)
class Phase:
    phase: int  # PlaceTile.Feedback phase constant
    duration: float  # s
    end: Point2  # base position when the phase ends


def _drive_time(model: MotionModel, start: Point2, end: Point2) -> float:
    return math.dist(start, end) / model.drive_speed


def footprints_overlap(centres: NDArray[np.float64], half_size: Point2, polygon: Polygon) -> NDArray[np.bool_]:
    """For (K, 2) centres of axis-aligned boxes, which overlap a convex polygon (separating axes)."""
    edges = np.roll(polygon, -1, axis=0) - polygon
    axes = np.vstack([[1.0, 0.0], [0.0, 1.0], np.column_stack([edges[:, 1], -edges[:, 0]])])
    box_radius = half_size[0] * np.abs(axes[:, 0]) + half_size[1] * np.abs(axes[:, 1])
    along = centres @ axes.T  # (K, axes)
    vertices = polygon @ axes.T  # (N, axes)
    separated = (along + box_radius < vertices.min(axis=0)) | (along - box_radius > vertices.max(axis=0))
    return ~separated.any(axis=1)


def footprint_overlaps(centre: Point2, half_size: Point2, polygon: Polygon) -> bool:
    """Whether an axis-aligned box and a convex polygon overlap."""
    return bool(footprints_overlap(np.array([centre], dtype=float), half_size, polygon)[0])


TURN_PENALTY = 0.02  # m per rad: of two stops equally near the tile, the one nearer the cache side wins


def approach_point(model: MotionModel, tile_xy: Point2, cache: Point2, obstacles: Sequence[Polygon] = ()) -> Point2:
    """Where the base stops to place a tile: `approach_distance` off the tile towards the cache.

    When its footprint would stand there on one of `obstacles` (the structure's tile footprints), it
    stops at the nearest point around the tile (headings every 5 degrees, distances every 1 cm) where
    it stands clear of all of them, as a robot drives round to the near side of the structure.
    """
    towards_cache = math.atan2(cache[1] - tile_xy[1], cache[0] - tile_xy[0])
    origin = np.asarray(tile_xy, dtype=float)
    if not obstacles:
        return stop_at(origin, towards_cache, model.approach_distance)
    half = (model.base_size[0] / 2 + model.base_clearance, model.base_size[1] / 2 + model.base_clearance)
    turns = np.radians(5.0 * np.arange(-35, 37))
    span = max(float(np.abs(p - origin).max()) for p in obstacles) + 2 * max(half)
    distances = model.approach_distance + 0.01 * np.arange(int(span / 0.01) + 1)
    headings = towards_cache + turns
    directions = np.column_stack([np.cos(headings), np.sin(headings)])
    stops = origin + distances[None, :, None] * directions[:, None, :]  # (headings, distances, 2)
    blocked = np.zeros(stops.shape[:2], dtype=bool)
    flat = stops.reshape(-1, 2)
    for polygon in obstacles:
        blocked |= footprints_overlap(flat, half, polygon).reshape(blocked.shape)
    clear = ~blocked
    nearest = np.argmax(clear, axis=1)  # first clear distance per heading
    cost = np.where(clear.any(axis=1), distances[nearest] + TURN_PENALTY * np.abs(turns), np.inf)
    best = int(np.argmin(cost))
    if not np.isfinite(cost[best]):
        return stop_at(origin, towards_cache, float(distances[-1]))
    return stop_at(origin, float(headings[best]), float(distances[nearest[best]]))


def stop_at(origin: NDArray[np.float64], heading: float, distance: float) -> Point2:
    return (float(origin[0] + distance * math.cos(heading)), float(origin[1] + distance * math.sin(heading)))


def placement_phases(
    model: MotionModel, start: Point2, cache: Point2, tile_xy: Point2, obstacles: Sequence[Polygon] = (),
    cache_stop: Point2 | None = None, target: Point2 | None = None,
) -> list[Phase]:
    """The timed phases of one placement (phase numbers of PlaceTile.Feedback); the base stops
    beside the cache on the side it comes from (or at `cache_stop`) and beside the tile clear of
    `obstacles` (see `approach_point`; or at `target`)."""
    at_cache = cache_stop or approach_point(model, cache, start)
    target = target or approach_point(model, tile_xy, cache, obstacles)
    return [
        Phase(1, _drive_time(model, start, at_cache), at_cache),  # DRIVING_TO_CACHE
        Phase(2, model.locate_time, at_cache),  # LOCATING_TILE
        Phase(3, model.pick_time, at_cache),  # PICKING
        Phase(4, _drive_time(model, at_cache, target), target),  # DRIVING_TO_STRUCTURE
        Phase(5, model.place_time, target),  # PLACING
        Phase(6, model.retreat_time, target),  # RETREATING
    ]


def drive_phase(model: MotionModel, start: Point2, end: Point2) -> Phase:
    """A drive with nothing in the arm (a robot going home): phase 0, no action phase of its own."""
    return Phase(0, _drive_time(model, start, end), end)


def removal_phases(
    model: MotionModel, start: Point2, tile_xy: Point2, drop_off: Point2, obstacles: Sequence[Polygon] = (),
    target: Point2 | None = None, drop_stop: Point2 | None = None,
) -> list[Phase]:
    """The timed phases of taking a tile off the structure (phase numbers of RemoveTile.Feedback):
    a placement run backwards, from the structure (or `target`) to beside the drop-off (or
    `drop_stop`), with the same arm times."""
    target = target or approach_point(model, tile_xy, drop_off, obstacles)
    at_drop = drop_stop or approach_point(model, drop_off, target)
    return [
        Phase(1, _drive_time(model, start, target), target),  # DRIVING_TO_STRUCTURE
        Phase(2, model.locate_time, target),  # LOCATING_TILE
        Phase(3, model.pick_time, target),  # LIFTING
        Phase(4, _drive_time(model, target, at_drop), at_drop),  # DRIVING_TO_DROP_OFF
        Phase(5, model.place_time, at_drop),  # RELEASING
        Phase(6, model.retreat_time, at_drop),  # RETREATING
    ]


def drive_time_to_pose(
    model: MotionModel, start: tuple[float, float, float], goal: tuple[float, float, float]
) -> float:
    """Seconds to drive a base from (x, y, yaw) to (x, y, yaw): turn, drive, turn."""
    heading = math.atan2(goal[1] - start[1], goal[0] - start[0]) if math.dist(start[:2], goal[:2]) > 1e-6 else start[2]
    turn1 = abs(math.remainder(heading - start[2], math.tau))
    turn2 = abs(math.remainder(goal[2] - heading, math.tau))
    return (turn1 + turn2) / model.turn_speed + _drive_time(model, start[:2], goal[:2])


def start_positions(tile_centres: list[Point2], count: int, clearance: float = 0.6) -> list[Point2]:
    """`count` robot start positions spread evenly on a circle around the structure, `clearance` (m)
    outside its outermost tile centre, so no robot starts inside the structure."""
    cx = sum(x for x, _ in tile_centres) / len(tile_centres)
    cy = sum(y for _, y in tile_centres) / len(tile_centres)
    radius = max(math.hypot(x - cx, y - cy) for x, y in tile_centres) + clearance
    return [
        (cx + radius * math.cos(-math.pi / 2 + 2 * math.pi * k / count),
         cy + radius * math.sin(-math.pi / 2 + 2 * math.pi * k / count))
        for k in range(count)
    ]
