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
    """Remembers each tile's last evidence per source (the VI robot whose fused states they are); a
    tile is fresh when its evidence from that source changed. Per source: with two VI robots on one
    topic, one robot's repeats of a stale "present" (its view blocked by a robot) alternated with the
    other's "missing" calls, so each repeat differed from the last message heard and counted as a new
    observation: 93 scans called a removed block present and no missing call was confirmed in 600 s."""

    last: dict[tuple[str, int], tuple[int, ...]] = field(default_factory=dict)

    def fresh(self, evidence: Mapping[int, tuple[int, ...]], source: str = "") -> set[int]:
        new = {tile for tile, e in evidence.items() if self.last.get((source, tile)) != e}
        self.last.update(((source, tile), e) for tile, e in evidence.items())
        return new

    def fresh_states(self, states: Iterable[TileEvidence], source: str = "") -> set[int]:
        """`fresh` of a `TileStateArray`'s states (`source`: its `robot_name`)."""
        evidence = {s.tile_id: (s.scan_count, s.physical_support, s.see_through_support) for s in states}
        return self.fresh(evidence, source)
