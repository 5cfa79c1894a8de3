"""Tile states from a scan that more than one alignment explains (an addition to paper section 2.2.1).

The paper aligns every scan to S_a by ICP from the overhead and floor estimates and trusts the one
pose it gets. A view of a few flat faces of a repetitive structure (the tops of parallel long
rectangles, two blocks of a gate) is explained just as well by poses several centimetres apart
along those faces: no measurement tells them apart (the true pose explains no more points, and no
more pixels of the depth image, than its rivals). Refusing such a scan left a third of the scans
of a build without tile states.

Instead, every rival alignment that passes the checks classifies the scan, and only what they all
say is kept: a tile keeps its state when every rival gives it that state, and is undetermined
otherwise. Its evidence (for fusion over scans) is the least every rival grants it, count by count,
when they agree (the share of pixels for it then stays on the side of their common verdict), and
nothing when they disagree. The true pose is among the rivals, so a verdict all of them share is
the true pose's verdict too. A misplacement all of them see is kept; one that a rival explains
away is dropped. A rival whose alignment fails its checks (a correction beyond the overhead
errors, pixels that contradict S_a) is left out; when the best fit fails them, the scan gives no
states at all (the caller's rule).

The same holds without a second fit when one tile is found moved with fewer than two tiles in place
beside it: the alignment rests on the few tiles it sees, so "that tile moved" and "the tile the
alignment rests on moved, and the scan with it" explain the points alike (`untold`). So is a tile
whose pixels agree while its points lean towards a motion that they do not confirm: the scan holds it
back from "in place", and its pixels must not add up to "in place" over scans either.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import fields, replace

import numpy as np

from vi_node.classify import TileState
from vi_node.evidence import TileEvidence
from vi_node.pose_prior import pose_error
from vi_node.scan_result import ScanResult, TileResult

SAME_POSE_SHIFT = 0.015  # m: rivals closer than this (and SAME_POSE_TURN) are one alignment
SAME_POSE_TURN = np.radians(1.5)


def distinct(results: Sequence[ScanResult]) -> list[ScanResult]:
    """The aligned `results`, best first, without those that ended where a better one did."""
    kept: list[ScanResult] = []
    for result in results:
        if not result.ok or result.camera_pose is None:
            continue
        if all(not _same_pose(result, other) for other in kept):
            kept.append(result)
    return kept


def agreed(rivals: Sequence[ScanResult]) -> ScanResult:
    """One result from several aligned results of the same scan (same tiles, same order): the first
    rival's, with only the states all of them share and the evidence all of them grant."""
    first = rivals[0]
    if len(rivals) == 1:
        return first
    states = np.array([[int(t.state) for t in r.tiles] for r in rivals])
    same = np.all(states == states[0], axis=0)
    tiles = [_tile_as_agreed(first.tiles[k], rivals, k, bool(same[k])) for k in range(len(first.tiles))]
    evidence = _least_evidence([r.evidence for r in rivals if r.evidence is not None], same)
    evidence_states = None
    if first.evidence_states is not None:
        stacked = np.array([r.evidence_states for r in rivals])
        evidence_states = np.where(
            np.all(stacked == stacked[0], axis=0), stacked[0], int(TileState.OCCLUDED)
        ).astype(np.int64)
    misplacement = {
        tile_id: entry
        for tile_id, entry in first.misplacement.items()
        if all(r.misplacement.get(tile_id, (False,))[0] == entry[0] for r in rivals[1:])
    }
    shifts = [pose_error(r.camera_pose, first.camera_pose) for r in rivals[1:]]  # type: ignore[arg-type]
    widest = max(shifts, key=lambda e: e[0])
    note = (
        f"alignment ambiguous: {len(rivals)} fits up to {widest[0] * 100:.0f} cm / {np.degrees(widest[1]):.0f} deg "
        f"apart; {int(np.count_nonzero(~same))} tile(s) they disagree on left undetermined"
    )
    return ScanResult(
        ok=True,
        tiles=tiles,
        camera_pose=first.camera_pose,
        alignment_rms=first.alignment_rms,
        candidates=first.candidates,
        timings=first.timings,
        notes=[*first.notes, note],
        tile_ids=first.tile_ids,
        evidence=evidence,
        evidence_states=evidence_states,
        misplacement=misplacement,
        rivals=len(rivals),
    )


def untold(result: ScanResult, tile_ids: Sequence[int], note: str = "") -> ScanResult:
    """`result` with `tile_ids` undetermined, as rivals that disagree leave a tile: no decisive pixels
    for fusion, and no misplacement verdict either way (neither a flag nor "in place")."""
    if not tile_ids:
        return result
    index = [k for k, t in enumerate(result.tile_ids) if t in tile_ids]
    same = np.ones(len(result.tile_ids), dtype=bool)
    same[index] = False
    evidence_states = None
    if result.evidence_states is not None:
        evidence_states = np.where(same, result.evidence_states, int(TileState.OCCLUDED)).astype(np.int64)
    return replace(
        result,
        tiles=[t if t.tile_id not in tile_ids else
               replace(t, state=TileState.OCCLUDED, physical=0, see_through=0, blank=0, offset=(0.0, 0.0, 0.0))
               for t in result.tiles],
        evidence=None if result.evidence is None else _least_evidence([result.evidence], same),
        evidence_states=evidence_states,
        misplacement={t: entry for t, entry in result.misplacement.items() if t not in tile_ids},
        notes=[*result.notes, note] if note else result.notes,
    )


def _same_pose(one: ScanResult, other: ScanResult) -> bool:
    shift, turn = pose_error(one.camera_pose, other.camera_pose)  # type: ignore[arg-type]
    return shift <= SAME_POSE_SHIFT and turn <= SAME_POSE_TURN


DECISIVE = ("agree", "see_through", "blank")  # TileEvidence counts for or against a tile
TILE_COUNTS = ("physical", "see_through", "blank", "judged")  # TileResult's counts the rivals share


def _tile_as_agreed(tile: TileResult, rivals: Sequence[ScanResult], index: int, same: bool) -> TileResult:
    """The first rival's tile result with the least counts every rival grants when they agree on
    its state; undetermined, with no decisive pixels, when they do not."""
    least = {name: min(getattr(r.tiles[index], name) for r in rivals) for name in TILE_COUNTS}
    if not same:
        return replace(tile, state=TileState.OCCLUDED, physical=0, see_through=0, blank=0, judged=least["judged"])
    return replace(tile, **least)


def _least_evidence(evidence: Sequence[TileEvidence], same: np.ndarray) -> TileEvidence | None:
    if not evidence:
        return None
    least = {f.name: np.min([getattr(e, f.name) for e in evidence], axis=0) for f in fields(TileEvidence)}
    for name in DECISIVE:
        least[name] = np.where(same, least[name], 0)
    return TileEvidence(**least)
