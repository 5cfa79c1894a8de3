"""Fusion of tile evidence across scans of the same expected structure (beyond paper section 2.2).

The paper re-scans from another position when a tile is occluded; here every scan's evidence is
kept per tile, so a tile undetermined from one view is resolved by adding what other views saw of
it. Tiles can be removed while the structure is built: when a scan's own pixels of a tile lean the
other way than the fused decision (most of them see through a tile fused present, or agree with a
tile fused missing), even too few of them to decide alone, the old evidence is dropped and the new
scan counts alone: the tile is undetermined until new views decide it (a tile
seen present and later seen missing is reported missing, and not present in between). A tile
fused missing that one scan then sees present is undetermined until a second view agrees: tiles
do not come back by themselves (a robot re-placing one reports it, and it starts afresh), and a
clutter box shaped like the missing block fit a 20-degree-off alignment that made it look present. A present
verdict also needs the latest view not to be split: when a scan's pixels of the tile lean neither way,
the older views do not vouch for it and it is undetermined until a view settles it. A scan that
glimpses a decided tile with too few pixels to lean either way leaves it as it is: its stale decision
is not reported as a new observation. A tile that is (re)placed starts afresh. A tile found
misplaced stays so until two scans see it present and in place, or one sees its place empty without
finding it moved nearby (then it is missing); the pixels of a scan that flags it count for neither
(a square swapped for a long rectangle, flagged from one view and seen missing from another, was
fused present on the third from the flagging view's pixels, which all agreed with the square, since
the rectangle covered its place): a tile does not move back onto its place by itself
(a repair re-places it, and it starts afresh), so one view of it in place after a flag leaves it
undetermined until another agrees (a cap turned 34 degrees, flagged from two bearings, was fused
present on the third, where its turn hid behind its neighbour's faces); a later scan that does not flag it
itself reports it with the counts of the scan that did, so that the flag is not taken for a new,
independent observation (`scan_freshness`): one misaligned scan flagged an octagon moved 3.6 cm, and
every later view repeated it until the auction node had it confirmed from two camera positions.

Paper mode fuses by its own rules: the latest scan that resolved a tile (present or missing)
decides it.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from vi_node.classify import TileState
from vi_node.evidence import EvidenceSettings, TileEvidence, decide, shown
from vi_node.scan_result import ScanResult, TileResult

RESOLVED = (TileState.PRESENT, TileState.MISSING)
MIN_LEANING_PIXELS = 3  # fewer observed pixels of a tile say nothing about a change


@dataclass
class FusedTile:
    evidence: TileEvidence  # summed since the tile last changed
    state: TileState  # decided on the summed evidence (or the latest resolved state, paper mode)
    scans: int = 0  # scans that saw the tile (virtual support > 0) since it last changed
    misplaced: bool = False
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)  # fitted x, y (m), yaw (rad) when misplaced
    residual: float = 0.0
    largest_view: int = 0  # most pixels of the tile judged in one scan
    shown: bool = False  # one scan's agreeing pixels were a fair share of the tile's view (`evidence.shown`)
    flagged_counts: tuple[int, int, int] | None = None  # (agree, see-through, scans) reported when last flagged
    seen_type: str = ""  # when misplaced: the type that lies there instead, if a scan could tell
    unflagged_once: bool = False  # flagged misplaced, then seen in place by one scan: undetermined until another

    def saw(self, mine: TileEvidence, settings: EvidenceSettings) -> None:
        """Note the size of one more scan's view of the tile."""
        self.largest_view = max(self.largest_view, int(mine.judged[0]))
        self.shown = self.shown or bool(shown(mine, settings)[0])


@dataclass
class TileFusion:
    """Evidence per tile id, across scans."""

    settings: EvidenceSettings = field(default_factory=EvidenceSettings)
    paper_rules: bool = False
    tiles: dict[int, FusedTile] = field(default_factory=dict)
    scans: int = 0

    def forget(self, tile_ids: Iterable[int] | None = None) -> None:
        """Drop the evidence of some tiles (re-placed, or no longer expected), or of all."""
        if tile_ids is None:
            self.tiles.clear()
            self.scans = 0
            return
        for tile_id in tile_ids:
            self.tiles.pop(int(tile_id), None)

    def add(
        self,
        tile_ids: Iterable[int],
        evidence: TileEvidence,
        states: Iterable[int],
        misplacement: dict[int, tuple[bool, tuple[float, float, float], float]] | None = None,
        seen_types: Mapping[int, str] | None = None,
    ) -> dict[int, FusedTile]:
        """Add one scan: per-tile evidence (arrays in `tile_ids` order) and the scan's own states.

        `misplacement` maps tile ids the scan could judge for misplacement to (flagged, offset,
        residual); `seen_types` the tiles it found another type lying in the place of to that type.
        Returns the fused view of exactly these tiles.
        """
        self.scans += 1
        ids = [int(t) for t in tile_ids]
        scan_states = [TileState(int(s)) for s in states]
        for k, (tile_id, scan_state) in enumerate(zip(ids, scan_states, strict=True)):
            mine = evidence.take(k)
            fused = self.tiles.get(tile_id)
            resolved = scan_state in RESOLVED
            flagged = bool(misplacement and misplacement.get(tile_id, (False,))[0])
            if fused is None:
                fused = FusedTile(TileEvidence.zeros(1) if flagged and not self.paper_rules else mine, scan_state)
                if not flagged:
                    fused.saw(mine, self.settings)
            elif self.paper_rules:
                fused.evidence = fused.evidence + mine
                if resolved or fused.state not in RESOLVED:
                    fused.state = scan_state
            elif flagged:
                pass  # what agrees with its planned pose is a tile near its place or of another shape
            elif fused.state in RESOLVED and int(mine.observed[0]) < MIN_LEANING_PIXELS:
                continue  # a glimpse: says nothing about a decided tile
            elif fused.state in RESOLVED and self._leaning(mine) not in (None, fused.state):
                # the tile changed: this scan counts alone; a missing tile does not come back by
                # itself (a re-placed one starts afresh), so one view of it there waits for another
                back = fused.state == TileState.MISSING and scan_state == TileState.PRESENT
                fused = FusedTile(mine, TileState.OCCLUDED if back else scan_state)
                fused.saw(mine, self.settings)
            else:
                fused.evidence = fused.evidence + mine
                fused.saw(mine, self.settings)
                fused.state = self._decide(fused)
                if fused.state == TileState.PRESENT and self._split(mine):
                    # older views must not vouch for a tile this view finds half gone: it may have just
                    # been taken away (or the view is off); undetermined until a view settles it
                    fused.state = TileState.OCCLUDED
            fused.scans += int(mine.virtual[0] > 0)
            if misplacement and tile_id in misplacement:
                flagged, offset, residual = misplacement[tile_id]
                if flagged:
                    fused.misplaced, fused.offset, fused.residual = True, offset, residual
                    fused.seen_type = (seen_types or {}).get(tile_id, "")
                    fused.unflagged_once = False
                elif scan_state == TileState.PRESENT:  # seen in place: put right once a second view agrees
                    fused.unflagged_once = fused.misplaced
                    fused.misplaced, fused.offset, fused.flagged_counts = False, (0.0, 0.0, 0.0), None
                    fused.seen_type = ""
            if scan_state == TileState.MISSING and not (misplacement and misplacement.get(tile_id, (False,))[0]):
                # its place seen empty, and nothing of it found moved nearby: missing, whatever an
                # older view flagged (a removed trapezoid flagged once stayed "misplaced" for 2 minutes,
                # and neither its re-placement nor a repair was ever asked for)
                fused.misplaced, fused.offset, fused.flagged_counts = False, (0.0, 0.0, 0.0), None
                fused.unflagged_once = False
            self.tiles[tile_id] = fused
        return {t: self.tiles[t] for t in ids}

    def _leaning(self, evidence: TileEvidence) -> TileState | None:
        """Which way a single scan's pixels of a tile point, however few (None: no clear way)."""
        agree, through = int(evidence.agree[0]), int(evidence.see_through[0])
        observed = agree + through
        if observed < MIN_LEANING_PIXELS:
            return None
        if through >= self.settings.missing_fraction * observed:
            return TileState.MISSING
        if agree >= self.settings.present_fraction * observed:
            return TileState.PRESENT
        return None

    def _split(self, evidence: TileEvidence) -> bool:
        """A scan saw enough of the tile to lean, but its pixels lean neither way."""
        return int(evidence.observed[0]) >= MIN_LEANING_PIXELS and self._leaning(evidence) is None

    def _decide(self, fused: FusedTile) -> TileState:
        """The evidence summed over the views, with "enough of the tile seen" measured against the
        view that showed most of it (summing what every view should see would ask for ever more)."""
        evidence = replace(fused.evidence, judged=np.array([fused.largest_view]), judgeable=np.zeros(1, np.int64))
        state = TileState(int(decide(evidence, self.settings)[0]))
        # views of a sliver do not add up to a view of the tile: one of them must have shown enough
        return TileState.OCCLUDED if state == TileState.PRESENT and not fused.shown else state

    def state_of(self, tile_id: int) -> TileState:
        fused = self.tiles.get(int(tile_id))
        if fused is None:
            return TileState.UNKNOWN
        if fused.misplaced:
            return TileState.MISPLACED
        if fused.unflagged_once:
            return TileState.OCCLUDED
        return fused.state

    def unresolved(self, tile_ids: Iterable[int]) -> list[int]:
        """Tiles with no decision yet (never seen, or only occluded so far)."""
        return [
            int(t)
            for t in tile_ids
            if self.state_of(t) not in (TileState.PRESENT, TileState.MISSING, TileState.MISPLACED)
        ]

    def summed(self, tile_ids: Iterable[int]) -> TileEvidence:
        """The fused evidence of `tile_ids` as arrays in that order (zeros for unseen tiles)."""
        ids = [int(t) for t in tile_ids]
        out = TileEvidence.zeros(len(ids))
        for k, tile_id in enumerate(ids):
            fused = self.tiles.get(tile_id)
            if fused is None:
                continue
            for name in ("agree", "see_through", "in_front", "no_return", "judged", "virtual"):
                getattr(out, name)[k] = getattr(fused.evidence, name)[0]
        return out

    def states(self, tile_ids: Iterable[int]) -> np.ndarray:
        return np.array([int(self.state_of(t)) for t in tile_ids], dtype=np.int64)


def fuse_scan(fusion: TileFusion, result: ScanResult) -> ScanResult:
    """Add a classified scan to `fusion`; the result with every tile's fused state and counts.

    A scan that could not be classified adds nothing and comes back unchanged.
    """
    if not result.ok or result.evidence is None or result.evidence_states is None:
        return result
    seen_types = {t.tile_id: t.seen_type for t in result.tiles if t.seen_type}
    fused = fusion.add(result.tile_ids, result.evidence, result.evidence_states, result.misplacement, seen_types)
    flagged_now = {t for t, (flagged, _, _) in (result.misplacement or {}).items() if flagged}
    tiles: list[TileResult] = []
    single = result.by_id()
    for tile_id in result.tile_ids:
        entry = fused[tile_id]
        e = entry.evidence
        agree, through, virtual = int(e.agree[0]), int(e.see_through[0]), int(e.virtual[0])
        scans = max(entry.scans, 1)
        if entry.misplaced and tile_id not in flagged_now and entry.flagged_counts is not None:
            agree, through, scans = entry.flagged_counts  # the flag of an older scan, repeated
        elif entry.misplaced:
            entry.flagged_counts = (agree, through, scans)
        if fusion.paper_rules:
            ratio = min(agree / virtual, virtual / agree) if agree and virtual else 0.0
        else:
            ratio = agree / (agree + through) if agree + through else 0.0
        tiles.append(
            TileResult(
                tile_id=tile_id,
                state=fusion.state_of(tile_id),
                physical=agree,
                virtual=virtual,
                ratio=ratio,
                residual=single[tile_id].residual,
                see_through=through,
                in_front=int(e.in_front[0]),
                no_return=int(e.no_return[0]),
                judged=int(e.judged[0]),
                offset=entry.offset if entry.misplaced else (0.0, 0.0, 0.0),
                scans=scans,
                seen_type=entry.seen_type if entry.misplaced else "",
            )
        )
    return replace(result, tiles=tiles, scan_count=fusion.scans)
