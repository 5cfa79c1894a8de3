"""Tiles a robot is placing right now (beyond paper section 2.2: S_a is "the tiles claimed placed").

A robot claims a tile placed when its place action ends, but the tile lies on the structure from the
moment the arm lets go: for the seconds of the retract and of the report's way, a camera sees a tile
that is not in S_a. Its points stand clear of every expected face at its neighbours' height, which is
what a tile of the wrong type looks like next to them: in a 4-robot pyramid trial, two neighbours
of just-placed tiles were confirmed misplaced from two camera positions and taken off for nothing.
So a tile some robot reported placing (`RobotStatus.PLACING`, its `current_tile`) within the last
`memory_ns` before a scan is "in hand" for that scan: the inspection expects it may be there
(its faces explain points, it may hide what lies behind it) but says nothing about it.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field


@dataclass
class TilesInHand:
    memory_ns: int  # ns a tile stays in hand after the last status that had a robot placing it
    _last_placing: dict[int, int] = field(default_factory=dict)  # tile id -> stamp (ns)

    def heard(self, placing: bool, tile_id: int, stamp_ns: int) -> None:
        """A robot status: placing `tile_id` (or not placing anything) at `stamp_ns`."""
        if placing and tile_id > 0:
            self._last_placing[tile_id] = max(stamp_ns, self._last_placing.get(tile_id, stamp_ns))

    def at(self, stamp_ns: int, expected: Iterable[int] = ()) -> frozenset[int]:
        """The tiles in hand for a scan taken at `stamp_ns`, other than the `expected` ones (a tile
        reported placed is in S_a)."""
        recent = {t for t, last in self._last_placing.items() if last >= stamp_ns - self.memory_ns}
        return frozenset(recent - set(expected))

    def forget_before(self, stamp_ns: int) -> None:
        """Drop what no scan after `stamp_ns` can need."""
        old = [t for t, last in self._last_placing.items() if last < stamp_ns - self.memory_ns]
        for tile_id in old:
            del self._last_placing[tile_id]
