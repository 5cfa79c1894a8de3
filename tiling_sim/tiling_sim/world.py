"""The physical structure S_p of the simulated testbed (paper section 2.2: S_p versus S_a).

Holds which tiles are physically in place. A placement is refused when a support of the tile is
not physically there (the robot would have nothing to put it on), and reported as already done
when the tile is in place. Only a tile with nothing resting on it can be taken away (the paper's
experimenters removed tiles by hand during the assembly).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

from tiling_assembly.structure import Structure


class PlaceCheck(Enum):
    OK = "ok"
    ALREADY_PRESENT = "already present"
    SUPPORT_MISSING = "support missing"
    UNKNOWN_TILE = "unknown tile"


@dataclass
class PhysicalWorld:
    structure: Structure
    present: set[int] = field(default_factory=set)

    def check_placement(self, tile_id: int) -> tuple[PlaceCheck, str]:
        """Whether `tile_id` can be placed now, with a one-line reason when not."""
        if tile_id not in self.structure.tiles:
            return PlaceCheck.UNKNOWN_TILE, f"tile {tile_id} is not part of {self.structure.name}"
        if tile_id in self.present:
            return PlaceCheck.ALREADY_PRESENT, f"tile {tile_id} is already in place"
        absent = self.absent_supports(tile_id)
        if absent:
            names = ", ".join(str(s) for s in absent)
            return PlaceCheck.SUPPORT_MISSING, f"tile {tile_id} cannot be placed: support {names} is not there"
        return PlaceCheck.OK, ""

    def absent_supports(self, tile_id: int) -> list[int]:
        """The supports of `tile_id` that are not physically there."""
        return sorted(s for s in self.structure.supports.get(tile_id, ()) if s not in self.present)

    def place(self, tile_id: int) -> None:
        check, reason = self.check_placement(tile_id)
        if check is not PlaceCheck.OK:
            raise ValueError(reason)
        self.present.add(tile_id)

    def removable(self) -> list[int]:
        """Present tiles with no present tile resting on them."""
        return sorted(
            t for t in self.present
            if not any(above in self.present for above in self.structure.supported_by[t])
        )

    def remove(self, tile_id: int) -> None:
        if tile_id not in self.removable():
            raise ValueError(f"tile {tile_id} cannot be removed: it is absent or carries other tiles")
        self.present.discard(tile_id)

    def complete(self) -> bool:
        return self.present == set(self.structure.tiles)
