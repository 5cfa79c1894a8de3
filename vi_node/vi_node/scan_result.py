"""What the inspection says about a scan (or about several scans fused): one result per tile."""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from vi_node.classify import TileState
from vi_node.evidence import TileEvidence

Array = NDArray[np.float64]


@dataclass
class TileResult:
    """What the inspection says about one expected tile.

    Paper mode: physical = p_i (points projecting onto the tile), virtual = v_i, ratio = min(p/v, v/p).
    Default mode: physical = pixels where only "the tile is there" explains the measurement,
    virtual = v_i, ratio = share of the decisive pixels that agree, see_through / blank (against
    it), ambiguous / in_front / no_return (saying nothing) the other judged pixels (`evidence`).
    Counts are summed over the scans fused (`scans`).
    """

    tile_id: int
    state: TileState
    physical: int
    virtual: int
    ratio: float
    residual: float = 0.0  # m, RMS distance of the tile's points to its expected faces
    see_through: int = 0
    in_front: int = 0
    no_return: int = 0
    judged: int = 0
    blank: int = 0  # blanks only "the tile is gone" explains (against it)
    ambiguous: int = 0  # measured where both "there" and "gone" explain it
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # MISPLACED: the tile's x, y (m), yaw (rad) motion
    scans: int = 1
    seen_type: str = ""  # MISPLACED: the tile type that lies there instead, when another type explains it


@dataclass
class ScanResult:
    """The outcome of one scan: tile results, or the reason there are none."""

    ok: bool
    reason: str = ""
    tiles: list[TileResult] = field(default_factory=list)
    camera_pose: Array | None = None  # 4x4 aligned pose of the optical frame in the map (P_v)
    alignment_rms: float = math.nan
    candidates: int = 0
    timings: dict[str, float] = field(default_factory=dict)  # stage -> seconds
    notes: list[str] = field(default_factory=list)  # warnings that did not stop the scan
    tile_ids: tuple[int, ...] = ()  # the expected tiles, in the order of the arrays below
    evidence: TileEvidence | None = None  # per-tile counts (paper mode: agree = p_i)
    evidence_states: NDArray[np.int64] | None = None  # states from the counts alone (no misplacement)
    misplacement: dict[int, tuple[bool, tuple[float, float, float], float]] = field(default_factory=dict)
    scan_count: int = 1  # scans fused into `tiles`
    doubt: str = ""  # why the pixels doubt the alignment (a result kept only to judge it once more)
    rivals: int = 1  # alignments that explain the scan equally well, whose shared verdicts these are

    def by_id(self) -> dict[int, TileResult]:
        return {t.tile_id: t for t in self.tiles}

    def moved_tiles(self) -> list[int]:
        """Tiles this scan flagged misplaced."""
        return [tile_id for tile_id, (flagged, _, _) in self.misplacement.items() if flagged]

    def without(self, tile_ids: Collection[int]) -> ScanResult:
        """The result with nothing said about `tile_ids` (tiles the scan expected but may not judge)."""
        if not tile_ids:
            return self
        keep = np.array([t not in tile_ids for t in self.tile_ids], dtype=bool)
        return replace(
            self,
            tiles=[t for t in self.tiles if t.tile_id not in tile_ids],
            tile_ids=tuple(t for t in self.tile_ids if t not in tile_ids),
            evidence=None if self.evidence is None else self.evidence.select(keep),
            evidence_states=None if self.evidence_states is None else self.evidence_states[keep],
            misplacement={t: m for t, m in self.misplacement.items() if t not in tile_ids},
        )
