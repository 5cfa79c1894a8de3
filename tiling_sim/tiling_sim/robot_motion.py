"""How long the simulated robots take (paper section 3.1: an M3 robot drives to the parts cache of
the tile's type, finds and picks the tile, drives to the structure and places it).

A placement is a sequence of timed phases from the robot's current position; durations follow
distance and speed, plus fixed pick and place times, all from `config/tiling_sim.yaml`. The robot
stands off the tile by `approach_distance` (the arm's reach) on the side facing its cache.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

Point2 = tuple[float, float]


@dataclass(frozen=True)
class MotionModel:
    drive_speed: float = 0.15  # m/s
    turn_speed: float = 1.0  # rad/s
    locate_time: float = 2.0  # s, laser scan at the cache
    pick_time: float = 6.0  # s, arm down, grasp, up
    place_time: float = 10.0  # s, arm out, release, back
    retreat_time: float = 2.0  # s, back off from the structure
    approach_distance: float = 0.25  # m from the tile's centre to where the base stops

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


def approach_point(model: MotionModel, tile_xy: Point2, cache: Point2) -> Point2:
    """Where the base stops to place a tile: off the tile towards the cache."""
    dx, dy = cache[0] - tile_xy[0], cache[1] - tile_xy[1]
    norm = math.hypot(dx, dy) or 1.0
    return (tile_xy[0] + dx / norm * model.approach_distance, tile_xy[1] + dy / norm * model.approach_distance)


def placement_phases(model: MotionModel, start: Point2, cache: Point2, tile_xy: Point2) -> list[Phase]:
    """The timed phases of one placement (phase numbers of PlaceTile.Feedback)."""
    target = approach_point(model, tile_xy, cache)
    return [
        Phase(1, _drive_time(model, start, cache), cache),  # DRIVING_TO_CACHE
        Phase(2, model.locate_time, cache),  # LOCATING_TILE
        Phase(3, model.pick_time, cache),  # PICKING
        Phase(4, _drive_time(model, cache, target), target),  # DRIVING_TO_STRUCTURE
        Phase(5, model.place_time, target),  # PLACING
        Phase(6, model.retreat_time, target),  # RETREATING
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
