"""The time model of assembly work (paper section 2.1 and its reference [11]).

One tile costs its robot the trip from the parts cache of the tile's type to the tile and the trip
back to a cache, plus the time to pick it up and to place it. The base stops an arm's reach short
of the cache (`cache_standoff`; 0 m: the paper's trips from the cache's centre) and, beside the
structure, where its footprint stands clear of every tile (`base_stops`: an arm's reach off the
tile on its cache's side, else round the tile; for a tile inside a pyramid, out at its edge). The
trip back goes to whichever cache the robot's next tile comes from: on average, the caches the
structure's tiles use, each as often as they are used. Against the same drives of the simulated
robots without other robots (pyramid_91 with 4 robots, paper_14 with 2), per robot within 7 s;
trips to the tile's centre and back to its own cache were 35 s short to 80 s over on pyramid_91
(a plan balanced on them left one robot working 9% longer than planned) and 9 s over on paper_14.
The planner balances these costs, the schedule simulation and the robots' bids (section 2.3: w_i,
the remaining workload) use them. Where the robots stand at the start is not the paper's (its
robots start at their caches): when it is known, `start_trips` is each robot's drive to the cache
of its first tile, which the schedule simulation adds before that tile.

Robots working close to each other cost time too: a robot that finds the stop it needs taken by
another robot drives round to another side (or waits). That is charged as a measured interference
cost, a time every pick costs this team on this structure (`for_team`), the larger of two:
- at the parts caches, which every robot visits for every tile: `cache_crowding` seconds for every
  robot beyond one per parts cache in use. Measured in the simulated team on pyramid_91 (4 robots,
  2 caches: 69 of 91 placements found a stop taken, 3.5 s per placement on average beyond the same
  drives alone);
- beside the structure: `stop_crowding` seconds for every other robot, times the share of the
  structure's stops that a base standing at one of them overlaps (`stop_share`). On a structure
  smaller than two bases every robot at it stands in another's way: paper_14 (2 robots, 5 caches, a
  base at one stop overlaps 44% of the others) lost 2.05 s per placement (27.0, 30.9 and 28.8 s over
  its 14 placements in three runs): 4.7 s per other robot and share; pyramid_91 (4 robots, 29%)
  lost 3.4-4.1 s: 3.9-4.7 s.
A robot held up at a crowded cache reaches the structure out of step with the others, and robots
with caches to spare meet at the structure, so the two are not added.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from tiling_assembly.base_stops import BaseGeometry, approach_stops
from tiling_assembly.structure import Structure


@dataclass(frozen=True)
class TimeModel:
    """Durations of assembly work (seconds) and the robots' travel speed (m/s)."""

    pick_time: float = 8.0  # s, find and grasp a tile at its cache
    place_time: float = 12.0  # s, lower, release and retract at the structure
    travel_speed: float = 0.15  # m/s, mean speed of a base between cache and structure
    cache_standoff: float = 0.25  # m, the base stops this far short of the cache (the arm's reach)
    type_place_time: Mapping[str, float] = field(default_factory=dict)  # s, per-type override
    cache_crowding: float = 3.5  # s per pick for every robot beyond one per parts cache (`for_team`)
    stop_crowding: float = 4.5  # s per pick for every other robot, times `stop_share` (`for_team`)
    crowding_time: float = 0.0  # s every pick costs this team on this structure (set by `for_team`)
    approach_distance: float = 0.25  # m from a tile's centre to where the base stops to place it (the arm's reach)
    base_size: tuple[float, float] = (0.33, 0.33)  # m, x and y size of a base's footprint, which stands off the tiles
    base_clearance: float = 0.03  # m a base keeps from every tile of the structure

    def __post_init__(self) -> None:
        for name, value in (("pick_time", self.pick_time), ("place_time", self.place_time),
                            ("cache_crowding", self.cache_crowding), ("stop_crowding", self.stop_crowding),
                            ("crowding_time", self.crowding_time)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number of seconds, got {value}")
        if not (math.isfinite(self.travel_speed) and self.travel_speed > 0):
            raise ValueError(f"travel_speed must be a positive number of m/s, got {self.travel_speed}")
        for name, value in (("cache_standoff", self.cache_standoff), ("approach_distance", self.approach_distance),
                            ("base_clearance", self.base_clearance)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number of m, got {value}")
        if len(self.base_size) != 2 or not all(math.isfinite(v) and v >= 0 for v in self.base_size):
            raise ValueError(f"base_size must be two non-negative numbers of m (x, y), got {list(self.base_size)}")
        for name, value in self.type_place_time.items():
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"type_place_time[{name}] must be a non-negative number of seconds")

    def place_duration(self, type_name: str) -> float:
        """Place time of one tile of `type_name` (s): lower, release and retract."""
        return self.type_place_time.get(type_name, self.place_time)

    def pick_duration(self) -> float:
        """Pick time of one tile (s), crowding at the caches included."""
        return self.pick_time + self.crowding_time

    def handling_time(self, type_name: str) -> float:
        """Pick plus place time of one tile of `type_name` (s)."""
        return self.pick_duration() + self.place_duration(type_name)

    def for_team(self, structure: Structure, robots: int) -> TimeModel:
        """This model for `robots` robots building `structure`: every pick costs the larger of
        `cache_crowding` s for each robot beyond one per parts cache the structure's tiles use (none
        without caches) and `stop_crowding` s for each other robot times `stop_share`."""
        caches = {structure.caches[t.type_name] for t in structure.tiles.values() if t.type_name in structure.caches}
        crowd = max(robots / len(caches) - 1.0, 0.0) if caches else 0.0
        at_structure = self.stop_crowding * max(robots - 1, 0) * self.stop_share(structure) if robots > 1 else 0.0
        return replace(self, crowding_time=max(self.cache_crowding * crowd, at_structure))

    def stop_share(self, structure: Structure) -> float:
        """The share of the other tiles' stops beside the structure that a base standing at a tile's
        stop overlaps, on average over the tiles (over 512 of them, evenly spread, on big structures)."""
        return _stop_share(structure.site, self.base())

    def cache_distance(self, structure: Structure, tile_id: int) -> float:
        """Floor distance from the tile's type cache to the tile's centre (m); 0 without a cache."""
        tile = structure.tiles[tile_id]
        cache = structure.caches.get(tile.type_name)
        if cache is None:
            return 0.0
        return math.hypot(tile.centroid[0] - cache[0], tile.centroid[1] - cache[1])

    def base(self) -> BaseGeometry:
        return BaseGeometry(self.approach_distance, (float(self.base_size[0]), float(self.base_size[1])),
                            self.base_clearance)

    def trips(self, structure: Structure) -> tuple[dict[int, float], dict[int, float]]:
        """Per tile id: `travel_time` and `return_time`, worked out once for the whole structure."""
        return _trips(structure.site, self.base(), self.cache_standoff, self.travel_speed)

    def travel_time(self, structure: Structure, tile_id: int) -> float:
        """Seconds of the trip from the stop beside the tile's type cache to the stop beside the tile."""
        return self.trips(structure)[0][tile_id]

    def return_time(self, structure: Structure, tile_id: int) -> float:
        """Seconds of the trip from the stop beside the tile back to a cache, on average over the
        caches the structure's tiles use."""
        return self.trips(structure)[1][tile_id]

    def tile_cost(self, structure: Structure, tile_id: int) -> float:
        """Seconds a robot spends on one tile: to the cache and back, pick and place."""
        to_tile, to_cache = self.trips(structure)
        return self.handling_time(structure.tiles[tile_id].type_name) + to_tile[tile_id] + to_cache[tile_id]

    def start_trips(self, structure: Structure, starts: Sequence[tuple[float, float]]) -> np.ndarray:
        """(robots, tiles in `structure.tiles` order): seconds from where each robot stands at the
        start to the stop beside the cache of each tile's type (0 for a tile without a cache)."""
        ids = list(structure.tiles)
        caches = [structure.caches.get(structure.tiles[t].type_name) for t in ids]
        has_cache = np.array([c is not None for c in caches], dtype=bool)
        towards = np.array([c if c is not None else (0.0, 0.0) for c in caches], dtype=float).reshape(-1, 2)
        where = np.asarray(starts, dtype=float).reshape(-1, 1, 2)
        trip = np.maximum(np.linalg.norm(where - towards[None, :, :], axis=-1) - self.cache_standoff, 0.0)
        return np.where(has_cache[None, :], trip / self.travel_speed, 0.0)

    def workload(self, structure: Structure, tile_ids: Iterable[int]) -> float:
        """Total cost of a set of tiles (s): a robot's workload w_i."""
        return float(sum((self.tile_cost(structure, t) for t in tile_ids), 0.0))


@lru_cache(maxsize=8)
def _stops(structure: Structure, base: BaseGeometry) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per tile (id order): where the base stops beside it coming from its cache, that cache (the
    tile's centre without one) and whether it has one."""
    ids = list(structure.tiles)
    centres = np.array([structure.tiles[t].centroid[:2] for t in ids], dtype=float).reshape(-1, 2)
    caches = [structure.caches.get(structure.tiles[t].type_name) for t in ids]
    has_cache = np.array([c is not None for c in caches], dtype=bool)
    towards = np.array([c if c is not None else centres[k] for k, c in enumerate(caches)], dtype=float)
    return approach_stops(structure, towards.reshape(-1, 2), base), towards.reshape(-1, 2), has_cache


@lru_cache(maxsize=8)
def _stop_share(structure: Structure, base: BaseGeometry) -> float:
    stops = _stops(structure, base)[0]
    count = len(stops)
    if count < 2:
        return 0.0
    probes = stops[:: max(1, count // 512)]
    reach = np.asarray(base.base_size) + base.clearance
    # stops sorted by x: each probe compares y only within its x window
    by_x = stops[np.argsort(stops[:, 0], kind="stable")]
    first = np.searchsorted(by_x[:, 0], probes[:, 0] - reach[0], side="right")
    last = np.searchsorted(by_x[:, 0], probes[:, 0] + reach[0], side="left")
    overlaps = sum(
        int(np.count_nonzero(np.abs(by_x[start:stop, 1] - probe[1]) < reach[1])) - 1
        for probe, start, stop in zip(probes, first, last, strict=True)
    )
    return float(overlaps / (len(probes) * (count - 1)))


@lru_cache(maxsize=8)
def _trips(
    structure: Structure, base: BaseGeometry, standoff: float, speed: float
) -> tuple[dict[int, float], dict[int, float]]:
    """Per tile id: seconds to the tile from its cache, and back to the caches in use (0 without a
    cache). Worked out once for all the structure's tiles: the stops need the whole footprint."""
    ids = list(structure.tiles)
    stops, towards, has_cache = _stops(structure, base)
    used, counts = np.unique(towards[has_cache], axis=0, return_counts=True)
    share = counts / max(int(counts.sum()), 1)

    def trip(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.maximum(np.linalg.norm(a - b, axis=-1) - standoff, 0.0) / speed

    outbound = np.where(has_cache, trip(stops, towards), 0.0)
    back = np.where(has_cache, trip(stops[:, None, :], used[None, :, :]) @ share, 0.0) if len(used) else outbound
    return dict(zip(ids, outbound.tolist(), strict=True)), dict(zip(ids, back.tolist(), strict=True))
