"""The time model of assembly work (paper section 2.1 and its reference [11]).

One tile costs its robot the trip between the parts cache of the tile's type and the tile, there
and back, plus the time to pick it up and to place it. The base stops an arm's reach short of the
cache (`cache_standoff`; 0 m: the paper's trips from the cache's centre); beside the structure it
stops clear of every tile, which on our structures costs about the drive to the tile's centre
(measured against the simulated robots: paper_14, pyramid_91 and arcade_294 within 5%). The
planner balances these costs, the schedule simulation and the robots' bids (section 2.3: w_i, the
remaining workload) use them.

Robots working close to each other cost time too, and most where they meet most: at the parts
caches, which every robot visits for every tile. A robot that finds the stop beside a cache taken
drives round to another side of it (or waits). That is charged as a measured interference cost:
`cache_crowding` seconds per pick for every robot beyond one per parts cache in use (`for_team`).
Measured in the simulated team on pyramid_91 (4 robots, 2 caches: 69 of 91 placements found a stop
taken, 3.5 s per placement on average beyond the same drives alone); paper_14 (2 robots, 5 caches)
lost 0.1 s per placement, and is charged nothing.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace

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
    crowding_time: float = 0.0  # s every pick costs this team on this structure (set by `for_team`)

    def __post_init__(self) -> None:
        for name, value in (("pick_time", self.pick_time), ("place_time", self.place_time),
                            ("cache_crowding", self.cache_crowding), ("crowding_time", self.crowding_time)):
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must be a non-negative number of seconds, got {value}")
        if not (math.isfinite(self.travel_speed) and self.travel_speed > 0):
            raise ValueError(f"travel_speed must be a positive number of m/s, got {self.travel_speed}")
        if not (math.isfinite(self.cache_standoff) and self.cache_standoff >= 0):
            raise ValueError(f"cache_standoff must be a non-negative number of m, got {self.cache_standoff}")
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
        """This model for `robots` robots building `structure`: every pick costs `cache_crowding` s
        for each robot beyond one per parts cache the structure's tiles use (none without caches)."""
        caches = {structure.caches[t.type_name] for t in structure.tiles.values() if t.type_name in structure.caches}
        crowd = max(robots / len(caches) - 1.0, 0.0) if caches else 0.0
        return replace(self, crowding_time=self.cache_crowding * crowd)

    def cache_distance(self, structure: Structure, tile_id: int) -> float:
        """Floor distance from the tile's type cache to the tile's centre (m); 0 without a cache."""
        tile = structure.tiles[tile_id]
        cache = structure.caches.get(tile.type_name)
        if cache is None:
            return 0.0
        return math.hypot(tile.centroid[0] - cache[0], tile.centroid[1] - cache[1])

    def travel_time(self, structure: Structure, tile_id: int) -> float:
        """Seconds of one trip between the tile's type cache and the tile (one way), from the stop
        beside the cache."""
        return max(self.cache_distance(structure, tile_id) - self.cache_standoff, 0.0) / self.travel_speed

    def tile_cost(self, structure: Structure, tile_id: int) -> float:
        """Seconds a robot spends on one tile: to the cache and back, pick and place."""
        travel = 2.0 * self.travel_time(structure, tile_id)
        return self.handling_time(structure.tiles[tile_id].type_name) + travel

    def workload(self, structure: Structure, tile_ids: Iterable[int]) -> float:
        """Total cost of a set of tiles (s): a robot's workload w_i."""
        return float(sum((self.tile_cost(structure, t) for t in tile_ids), 0.0))
