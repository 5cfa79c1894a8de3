"""Loading and validating structure files: the contract's rules, one malformed file per rule."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from conftest import DATA, STRUCTURES

from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure

INVALID = sorted((DATA / "structures" / "invalid").glob("*.yaml"))


def _expectation(path: Path) -> tuple[str, tuple[int, ...]]:
    """The `# expect: RULE [ID ...]` header of a malformed file (binary files expect 'file')."""
    try:
        first = path.read_text(encoding="utf-8").splitlines()[0]
    except UnicodeDecodeError:
        return "file", ()
    match = re.match(r"# expect: (\S+)((?: \d+)*)$", first)
    assert match, f"{path.name} lacks an '# expect: RULE [IDS]' header"
    return match.group(1), tuple(int(i) for i in match.group(2).split())


def test_there_are_at_least_twenty_malformed_files() -> None:
    assert len(INVALID) >= 20


@pytest.mark.parametrize("path", INVALID, ids=[p.stem for p in INVALID])
def test_malformed_file_is_rejected_naming_file_rule_and_tiles(path: Path) -> None:
    rule, ids = _expectation(path)
    with pytest.raises(StructureError) as raised:
        load_structure(path)
    error = raised.value
    assert (error.rule, error.tile_ids) == (rule, ids)
    message = str(error)
    assert "\n" not in message
    assert message.startswith(f"{path}: {rule}")
    for tile_id in ids:
        assert re.search(rf"\b{tile_id}\b", message)


def test_missing_file_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(StructureError, match=r"nowhere\.yaml: file: cannot read the file: No such file"):
        load_structure(tmp_path / "nowhere.yaml")


def test_paper_structure_matches_the_paper() -> None:
    structure = load_structure(STRUCTURES / "paper_14.yaml")
    assert len(structure) == 14
    assert set(structure.tile_types) == {"long_rectangle", "trapezoid", "octagon", "square", "triangle"}
    types = {i: t.type_name for i, t in structure.tiles.items()}
    # ids and types of the paper's Tables 1 and 2
    expected = {
        3: "long_rectangle", 6: "trapezoid", 4: "octagon", 9: "square", 11: "long_rectangle",
        13: "triangle", 7: "trapezoid", 5: "octagon", 8: "square", 10: "square",
        12: "long_rectangle", 14: "triangle",
    }
    assert {i: types[i] for i in expected} == expected
    for tile_type in structure.tile_types.values():
        extent = tile_type.shape.vertices.max(axis=0) - tile_type.shape.vertices.min(axis=0)
        assert 0.04 - 1e-9 <= max(extent[:2]) <= 0.17 + 1e-9  # side lengths 4-17 cm
    assert structure.tiles_by_layer() == [[1, 2, 3, 6, 7], [4, 5, 8, 9], [10, 11, 12], [13, 14]]
    assert dict(structure.supports) == {
        1: (), 2: (), 3: (), 6: (), 7: (),
        4: (1, 2, 3, 6), 5: (1, 2, 3, 7), 8: (7,), 9: (6,),
        10: (5,), 11: (4, 9), 12: (5, 8), 13: (11,), 14: (12,),
    }
    assert set(structure.caches) == set(structure.tile_types)


@pytest.mark.parametrize("name, tiles", [("paper_14", 14), ("pyramid_91", 91), ("gate_9", 9)])
def test_example_structures_load(name: str, tiles: int) -> None:
    structure = load_structure(STRUCTURES / f"{name}.yaml")
    assert len(structure) == tiles
    # every tile above the floor has a support, and supports are lower than what they carry
    for tile_id, below in structure.supports.items():
        tile = structure.tiles[tile_id]
        if tile.aabb[0][2] > 1e-6:
            assert below
        for s in below:
            assert structure.tiles[s].aabb[0][2] < tile.aabb[0][2]


def test_pyramid_tiles_rest_on_four(tmp_path: Path) -> None:
    structure = load_structure(STRUCTURES / "pyramid_91.yaml")
    layers = structure.tiles_by_layer()
    assert [len(layer) for layer in layers] == [36, 25, 16, 9, 4, 1]
    for layer in layers[1:]:
        for tile_id in layer:
            assert len(structure.supports[tile_id]) == 4


def test_explicit_supports_replace_derived_ones(tmp_path: Path) -> None:
    path = tmp_path / "explicit.yaml"
    path.write_text(
        """
tile_types:
  slab: {prism: {polygon: [[-0.05, -0.02], [0.05, -0.02], [0.05, 0.02], [-0.05, 0.02]], height: 0.02}}
tiles:
  - {id: 1, type: slab, position: [-0.03, 0, 0]}
  - {id: 2, type: slab, position: [0.03, 0.05, 0]}
  - {id: 3, type: slab, position: [0, 0.025, 0.02], yaw: 1.5707963}
  - {id: 4, type: slab, position: [0, 0.025, 0.04], supports: [3, 1]}
"""
    )
    structure = load_structure(path)
    assert structure.supports[3] == (1, 2)
    assert structure.supports[4] == (1, 3)
    assert structure.layers[4] == 2


def test_duplicate_yaml_keys_inside_a_tile_are_rejected(tmp_path: Path) -> None:
    path = tmp_path / "dup.yaml"
    path.write_text(
        "tile_types:\n  s: {prism: {polygon: [[0, 0], [0.1, 0], [0, 0.1]], height: 0.02}}\n"
        "tiles:\n  - {id: 1, type: s, position: [0, 0, 0], position: [1, 0, 0]}\n"
    )
    with pytest.raises(StructureError, match="duplicate key 'position'"):
        load_structure(path)
