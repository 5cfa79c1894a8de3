"""Which tiles of a fused tile-state array the latest scan actually saw (paper section 2.2).

The inspection publishes fused states: a tile the latest scan did not see keeps the state older
scans gave it, with the same evidence (scans that contributed, support counts). Such a repeat is
not a new, independent observation: it must not confirm a missing tile (auction node) nor count
as having looked at the tile (VI robot's exploration).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Protocol


class TileEvidence(Protocol):
    tile_id: int
    scan_count: int
    physical_support: int
    see_through_support: int


@dataclass
class RepeatFilter:
    """Remembers each tile's last evidence; a tile is fresh when its evidence changed."""

    last: dict[int, tuple[int, ...]] = field(default_factory=dict)

    def fresh(self, evidence: Mapping[int, tuple[int, ...]]) -> set[int]:
        new = {tile for tile, e in evidence.items() if self.last.get(tile) != e}
        self.last.update(evidence)
        return new

    def fresh_states(self, states: Iterable[TileEvidence]) -> set[int]:
        """`fresh` of a `TileStateArray`'s states."""
        return self.fresh({s.tile_id: (s.scan_count, s.physical_support, s.see_through_support) for s in states})
