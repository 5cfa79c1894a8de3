"""The shifts that map S_a nearly onto itself: the alignments a periodic structure cannot rule out."""

from __future__ import annotations

import numpy as np
from vi_helpers import structure

from tiling_assembly.structure_file import parse_structure
from vi_node.periodicity import periodic_shifts

SLAB = {"prism": {"polygon": [[-0.04, -0.04], [0.04, -0.04], [0.04, 0.04], [-0.04, 0.04]], "height": 0.02}}
BAR = {"prism": {"polygon": [[-0.04, -0.02], [0.04, -0.02], [0.04, 0.02], [-0.04, 0.02]], "height": 0.02}}


def row(types: list[str], pitch: float = 0.1, yaws: list[float] | None = None) -> list:
    tiles = [{"id": k + 1, "type": kind, "position": [k * pitch, 0.0, 0.0], "yaw": (yaws or [0.0] * len(types))[k]}
             for k, kind in enumerate(types)]
    built = parse_structure({"name": "row", "frame_id": "map", "tile_types": {"slab": SLAB, "bar": BAR},
                             "tiles": tiles}, "row.yaml")
    return [built.tiles[i] for i in built.tile_ids]


def rounded(shifts: list[np.ndarray]) -> set[tuple[float, float]]:
    return {(round(float(x), 3), round(float(y), 3)) for x, y in shifts}


def test_a_grid_of_equal_slabs_repeats_at_its_pitch_and_the_lab_structure_does_not_repeat() -> None:
    pyramid = structure("pyramid_91")
    shifts = rounded(periodic_shifts([pyramid.tiles[i] for i in pyramid.tile_ids], within=0.10))
    assert {(0.08, 0.0), (-0.08, 0.0), (0.0, 0.08), (0.0, -0.08)} <= shifts
    assert all(0.03 <= np.hypot(*shift) <= 0.10 for shift in shifts)
    paper = structure("paper_14")
    assert periodic_shifts([paper.tiles[i] for i in paper.tile_ids], within=0.10) == []


def test_a_row_repeats_at_its_pitch_only_where_equal_tiles_meet_equal_tiles() -> None:
    assert rounded(periodic_shifts(row(["slab"] * 5), within=0.12)) == {(0.1, 0.0), (-0.1, 0.0)}
    alternating = row(["slab", "bar"] * 3)
    assert periodic_shifts(alternating, within=0.12) == []  # one pitch puts bars on slabs
    assert rounded(periodic_shifts(alternating, within=0.25)) == {(0.2, 0.0), (-0.2, 0.0)}


def test_a_turned_tile_does_not_stand_in_for_an_unturned_one() -> None:
    assert periodic_shifts(row(["bar"] * 4, yaws=[0.0, 1.5708] * 2), within=0.12) == []
    assert len(periodic_shifts(row(["bar"] * 4), within=0.12)) == 2
