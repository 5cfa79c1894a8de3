"""Shifts that map S_a nearly onto itself (an addition to paper section 2.2.1).

The paper aligns each scan to S_a by ICP from the overhead estimate. A periodic structure (a grid
of equal slabs, a row of equal piers) looks the same shifted by one pitch: a view of part of it is
explained by an alignment one pitch off as well as by the true one, or a little better (the scan's
edge happens to meet a neighbour's face), and the coarse search need not offer the true one at
all. Trusted, that alignment calls present tiles at the structure's edge missing. The shifts are
found here once per S_a, so that the pipeline can try its best fit moved by each of them as a
rival (`rival_fits`): a tile the rivals disagree on stays undetermined.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from tiling_assembly.geometry import PlacedTile

SAME_PLACE = 0.005  # m: tile origins this close are one place
MIN_SHARE = 0.5  # a shift must move this share of S_a's tiles onto equal tiles of S_a
MAX_TILES = 3000  # tiles of S_a the candidate shifts are taken from (all are checked)


def periodic_shifts(tiles: Sequence[PlacedTile], within: float, shortest: float = 0.03) -> list[np.ndarray]:
    """The horizontal shifts (x, y), `shortest` to `within` m long, that move at least `MIN_SHARE`
    of `tiles` onto a tile of the same type, orientation and height: the structure's periods
    within the reach of the overhead errors. Longest share first."""
    if len(tiles) < 2:
        return []
    kinds = [_kind(tile) for tile in tiles]
    xy = np.array([tile.position[:2] for tile in tiles])
    places = {(kind, *np.round(p / SAME_PLACE).astype(int)) for kind, p in zip(kinds, xy, strict=True)}
    shares: list[tuple[float, np.ndarray]] = []
    for shift in _candidate_shifts(kinds, xy, within, shortest):
        moved = np.round((xy + shift) / SAME_PLACE).astype(int)
        share = sum((kind, *cell) in places for kind, cell in zip(kinds, moved, strict=True)) / len(tiles)
        if share >= MIN_SHARE:
            shares.append((share, shift))
    shares.sort(key=lambda entry: -entry[0])
    return [shift for _, shift in shares]


def _kind(tile: PlacedTile) -> tuple[object, ...]:
    """What must match for a tile to stand in for another: type, orientation, height."""
    return (tile.type_name, *np.round(tile.rotation, 2).ravel(), round(float(tile.position[2]) / SAME_PLACE))


def _candidate_shifts(kinds: list[tuple[object, ...]], xy: np.ndarray, within: float,
                      shortest: float) -> list[np.ndarray]:
    """Distinct differences between origins of equal tiles, `shortest` to `within` m long."""
    n = min(len(xy), MAX_TILES)
    codes = {kind: code for code, kind in enumerate(dict.fromkeys(kinds[:n]))}
    kind_codes = np.array([codes[kind] for kind in kinds[:n]])
    same = kind_codes[:, None] == kind_codes[None, :]
    differences = (xy[None, :n] - xy[:n, None])[same]
    lengths = np.linalg.norm(differences, axis=1)
    differences = differences[(lengths >= shortest) & (lengths <= within)]
    cells = np.unique(np.round(differences / SAME_PLACE).astype(int), axis=0)
    return [cell * SAME_PLACE for cell in cells]
