"""The physical structure S_p of the simulated testbed (paper section 2.2: S_p versus S_a).

Holds which tiles are physically in place, and how a tile that did not land as planned really
lies (beyond the paper, its future work: shifted, turned, or a tile of the wrong type put in its
place). A placement is refused when a support of the tile is not physically there (the robot would
have nothing to put it on) or lies wrong (the tile would not sit as planned), and when a wrong tile
takes up part of its footprint; it is reported as already done when the tile is in place. Only a
tile with nothing resting on it can be taken away (the paper's experimenters removed tiles by hand
during the assembly).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

import numpy as np

from tiling_assembly.contacts import separation
from tiling_assembly.geometry import PlacedTile, rotation_from_rpy
from tiling_assembly.structure import Structure

# tiles at the same height that reach further into each other collide: solid tiles cannot, the slack
# is the placing noise of planned neighbours that touch (the inspection believes motions up to 5 mm)
PENETRATION = 0.002  # m


@dataclass(frozen=True)
class Misplacement:
    """How a tile really lies when it did not land as planned: moved by `shift` (m, in the map)
    and turned by `turn` (rad, about the vertical through its centre), or a tile of `type_name`
    lying where the planned tile should."""

    shift: tuple[float, float] = (0.0, 0.0)
    turn: float = 0.0
    type_name: str | None = None

    @property
    def kind(self) -> str:
        """"shift", "turn" or "wrong_type" (the names of results.json)."""
        if self.type_name is not None:
            return "wrong_type"
        return "turn" if self.turn else "shift"

    def describe(self) -> str:
        if self.type_name is not None:
            return f"a {self.type_name} in its place"
        if self.turn:
            return f"turned {math.degrees(self.turn):+.0f} deg"
        return f"shifted {math.hypot(*self.shift) * 100:.1f} cm"


def collide(a: PlacedTile, b: PlacedTile) -> bool:
    """Whether two tiles at the same height reach more than PENETRATION into each other (tiles that
    only touch, or rest one on the other, do not). A 4 cm square turned 30 degrees beside a long
    rectangle it touched pokes 7 mm into it: that is no place a tile can lie (1 cm^2 of shared
    footprint, the rule before, let it, and the inspection rightly refused to believe it)."""
    (a_low, a_high), (b_low, b_high) = a.aabb, b.aabb
    if b_low[2] >= a_high[2] - 1e-4 or b_high[2] <= a_low[2] + 1e-4:
        return False
    if np.any(a_low[:2] > b_high[:2]) or np.any(b_low[:2] > a_high[:2]):
        return False
    return separation(a, b) < -PENETRATION


def actual_tile(structure: Structure, tile_id: int, misplacement: Misplacement | None) -> PlacedTile:
    """The geometry of what really lies at `tile_id`'s place."""
    planned = structure.tiles[tile_id]
    if misplacement is None:
        return planned
    if misplacement.type_name is not None:
        other = structure.tile_types[misplacement.type_name]
        return PlacedTile(tile_id, other.name, other.shape, planned.rotation, planned.position)
    turn = rotation_from_rpy(0.0, 0.0, misplacement.turn)
    centre = planned.centroid
    position = turn @ (planned.position - centre) + centre + np.array([*misplacement.shift, 0.0])
    return PlacedTile(tile_id, planned.type_name, planned.shape, turn @ planned.rotation, position)


class PlaceCheck(Enum):
    OK = "ok"
    ALREADY_PRESENT = "already present"
    SUPPORT_MISSING = "support missing"
    UNKNOWN_TILE = "unknown tile"
    BLOCKED = "blocked by a wrong tile"


@dataclass
class PhysicalWorld:
    structure: Structure
    present: set[int] = field(default_factory=set)
    misplaced: dict[int, Misplacement] = field(default_factory=dict)  # present tiles that lie wrong

    def check_placement(self, tile_id: int) -> tuple[PlaceCheck, str]:
        """Whether `tile_id` can be placed now, with a one-line reason when not."""
        if tile_id not in self.structure.tiles:
            return PlaceCheck.UNKNOWN_TILE, f"tile {tile_id} is not part of {self.structure.name}"
        if tile_id in self.misplaced:
            return PlaceCheck.BLOCKED, (f"tile {tile_id} cannot be placed: it is there already but lies wrong "
                                        f"({self.misplaced[tile_id].describe()})")
        if tile_id in self.present:
            return PlaceCheck.ALREADY_PRESENT, f"tile {tile_id} is already in place"
        absent = self.absent_supports(tile_id)
        if absent:
            names = ", ".join(str(s) for s in absent)
            return PlaceCheck.SUPPORT_MISSING, f"tile {tile_id} cannot be placed: support {names} is not there"
        wrong_below = self.wrong_supports(tile_id)
        if wrong_below:
            below = wrong_below[0]
            return PlaceCheck.BLOCKED, (f"tile {tile_id} cannot be placed: its support {below} lies wrong "
                                        f"({self.misplaced[below].describe()})")
        in_the_way = self.wrong_tiles_in_the_way(tile_id)
        if in_the_way:
            other = in_the_way[0]
            return PlaceCheck.BLOCKED, (f"tile {tile_id} cannot be placed: tile {other} lies in the way "
                                        f"({self.misplaced[other].describe()})")
        return PlaceCheck.OK, ""

    def wrong_supports(self, tile_id: int) -> list[int]:
        """Supports of `tile_id` that lie shifted or turned: nothing sits on them as planned. A tile of
        the wrong type has the right height (the mix-up is between types of one height), so a tile
        can rest on it, and comes off with it when it is repaired."""
        return [s for s in self.structure.supports.get(tile_id, ())
                if s in self.misplaced and self.misplaced[s].type_name is None]

    def blocking(self, tile_id: int) -> list[int]:
        """The tiles lying wrong that keep `tile_id` from its planned place: itself, its supports
        lying off, or in its way."""
        if tile_id in self.misplaced:
            return [tile_id]
        return sorted({*self.wrong_supports(tile_id), *self.wrong_tiles_in_the_way(tile_id)})

    def resting_on(self, tile_id: int) -> list[int]:
        """The present tiles resting directly on `tile_id`."""
        return sorted(t for t in self.structure.supported_by[tile_id] if t in self.present)

    def wrong_tiles_in_the_way(self, tile_id: int) -> list[int]:
        """The misplaced tiles that take up part of the room `tile_id` needs."""
        planned = self.structure.tiles[tile_id]
        return [other for other in sorted(self.misplaced) if collide(planned, self.actual(other))]

    def room_for(self, tile_id: int, misplacement: Misplacement) -> bool:
        """Whether `tile_id` can land as `misplacement` says without going through a present tile
        (a tile that would land there stops as planned instead)."""
        real = actual_tile(self.structure, tile_id, misplacement)
        return not any(collide(real, self.actual(other)) for other in self.present if other != tile_id)

    def actual(self, tile_id: int) -> PlacedTile:
        """What really lies at a present tile's place (for the Kinect and the overhead cameras)."""
        return actual_tile(self.structure, tile_id, self.misplaced.get(tile_id))

    def absent_supports(self, tile_id: int) -> list[int]:
        """The supports of `tile_id` that are not physically there."""
        return sorted(s for s in self.structure.supports.get(tile_id, ()) if s not in self.present)

    def place(self, tile_id: int, misplacement: Misplacement | None = None) -> None:
        """Put `tile_id` in place; `misplacement`: how it really lands when not as planned."""
        check, reason = self.check_placement(tile_id)
        if check is not PlaceCheck.OK:
            raise ValueError(reason)
        if misplacement is not None and not self.room_for(tile_id, misplacement):
            raise ValueError(f"tile {tile_id} cannot land {misplacement.describe()}: a present tile is there")
        self.present.add(tile_id)
        if misplacement is not None:
            self.misplaced[tile_id] = misplacement

    def removable(self) -> list[int]:
        """Present tiles with no present tile resting on them."""
        return sorted(t for t in self.present if not self.resting_on(t))

    def remove(self, tile_id: int) -> None:
        if tile_id not in self.removable():
            raise ValueError(f"tile {tile_id} cannot be removed: it is absent or carries other tiles")
        self.present.discard(tile_id)
        self.misplaced.pop(tile_id, None)

    def complete(self) -> bool:
        """Every tile in place, and as planned."""
        return self.present == set(self.structure.tiles) and not self.misplaced
