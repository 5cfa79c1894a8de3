"""Tile geometry, contacts and support derivation, without ROS."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml
from conftest import STRUCTURES
from hypothesis import given, settings
from hypothesis import strategies as st

from tiling_assembly import contacts, polygons
from tiling_assembly.geometry import (
    PlacedTile,
    convex_shape,
    prism_shape,
    quaternion_from_rotation,
    rotation_from_quaternion,
    rotation_from_rpy,
    rpy_from_rotation,
)
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure, parse_structure

angles = st.floats(min_value=-3.1, max_value=3.1)


@given(angles, st.floats(min_value=-1.5, max_value=1.5), angles)
def test_rotation_conversions_round_trip(roll: float, pitch: float, yaw: float) -> None:
    rotation = rotation_from_rpy(roll, pitch, yaw)
    assert np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-12)
    assert np.allclose(rotation_from_rpy(*rpy_from_rotation(rotation)), rotation, atol=1e-9)
    assert np.allclose(rotation_from_quaternion(*quaternion_from_rotation(rotation)), rotation, atol=1e-9)


def test_rpy_convention_is_fixed_axis_xyz() -> None:
    # yaw turns x towards y; pitch turns z towards x; roll turns y towards z (REP 103)
    assert np.allclose(rotation_from_rpy(0, 0, math.pi / 2) @ [1, 0, 0], [0, 1, 0])
    assert np.allclose(rotation_from_rpy(0, math.pi / 2, 0) @ [0, 0, 1], [1, 0, 0])
    assert np.allclose(rotation_from_rpy(math.pi / 2, 0, 0) @ [0, 1, 0], [0, 0, 1])


def _closed_and_outward(tile: PlacedTile) -> None:
    centre = tile.centroid
    area_vector = np.zeros(3)
    for k, normal in enumerate(tile.face_normals):
        corners = tile.face_corners(k)
        assert np.allclose((corners - corners[0]) @ normal, 0, atol=1e-9), "face is not planar"
        assert normal @ (corners.mean(axis=0) - centre) > 0, "normal points inwards"
        tris, faces = tile.triangles
        for tri in tris[faces == k]:
            a, b, c = tile.vertices[tri]
            cross = np.cross(b - a, c - a)
            assert cross @ normal > 0, "triangle wound against its face"
            area_vector += cross / 2
    assert np.allclose(area_vector, 0, atol=1e-12), "surface is not closed"


def test_prism_faces_are_planar_outward_and_closed() -> None:
    octagon = load_structure(STRUCTURES / "paper_14.yaml").tiles[4]
    assert len(octagon.shape.faces) == 10
    _closed_and_outward(octagon)
    side = 2 * 0.05 * math.tan(math.pi / 8)
    assert octagon.volume == pytest.approx(2 * (1 + math.sqrt(2)) * side**2 * 0.02, rel=1e-3)


def test_clockwise_polygon_is_reoriented() -> None:
    shape = prism_shape(np.array([[0, 0], [0, 0.1], [0.1, 0.1], [0.1, 0]], float), 0.02)
    assert polygons.signed_area(shape.polygon) > 0
    tile = PlacedTile(1, "box", shape, rotation_from_rpy(0.3, -0.2, 1.0), np.array([1.0, 2.0, 0.5]))
    _closed_and_outward(tile)
    assert tile.volume == pytest.approx(0.0002)


def test_non_convex_prism_is_split_into_convex_pieces() -> None:
    l_shape = np.array([[0, 0], [0.1, 0], [0.1, 0.04], [0.04, 0.04], [0.04, 0.1], [0, 0.1]], float)
    shape = prism_shape(l_shape, 0.02)
    assert len(shape.pieces) == 4
    tile = PlacedTile(1, "ell", shape, np.eye(3), np.zeros(3))
    _closed_and_outward(tile)
    assert tile.volume == pytest.approx((0.1 * 0.1 - 0.06 * 0.06) * 0.02)
    assert polygons.signed_area(tile.footprint) == pytest.approx(0.1 * 0.1 - 0.06 * 0.06)


def test_convex_polytope_faces_are_merged_per_plane() -> None:
    gate = load_structure(STRUCTURES / "gate_9.yaml")
    wedge = gate.tiles[7]
    assert wedge.shape.kind == "convex"
    assert sorted(len(f.loop) for f in wedge.shape.faces) == [3, 3, 4, 4, 4]
    _closed_and_outward(wedge)
    assert wedge.volume == pytest.approx(0.06 * 0.06 * 0.04 / 2)
    assert gate.supports[6] == (5,) and gate.supports[7] == (5,)


L_SHAPE_FILE = """
tile_types:
  ell: {prism: {polygon: [[0, 0], [0.1, 0], [0.1, 0.04], [0.04, 0.04], [0.04, 0.1], [0, 0.1]], height: 0.02}}
  square: {prism: {polygon: [[-0.02, -0.02], [0.02, -0.02], [0.02, 0.02], [-0.02, 0.02]], height: 0.02}}
tiles:
  - {id: 1, type: ell, position: [0, 0, 0]}
  - {id: 2, type: square, position: [0.075, 0.075, 0]}
  - {id: 3, type: square, position: [0.075, 0.075, 0.02]}
  - {id: 4, type: square, position: [0.02, 0.08, 0.02]}
"""


def test_supports_follow_the_real_outline_of_a_non_convex_tile() -> None:
    structure = parse_structure(yaml.safe_load(L_SHAPE_FILE), "ell.yaml")
    # the square in the L's notch touches it only at a corner: no contact along a face
    assert structure.supports == {1: (), 2: (), 3: (2,), 4: (1,)}
    # a tile floating over the notch (its box overlaps the L's box) rests on nothing
    floating = yaml.safe_load(L_SHAPE_FILE)
    floating["tiles"] = [floating["tiles"][0], {"id": 5, "type": "square", "position": [0.07, 0.07, 0.02]}]
    with pytest.raises(StructureError) as raised:
        parse_structure(floating, "ell.yaml")
    assert raised.value.rule == "floating" and raised.value.tile_ids == (5,)


def test_support_on_a_sloped_face() -> None:
    a = 0.06
    lower = [[0, 0, 0], [a, 0, 0], [0, 0, a], [0, a, 0], [a, a, 0], [0, a, a]]
    upper = [[a, 0, 0], [a, 0, a], [0, 0, a], [a, a, 0], [a, a, a], [0, a, a]]
    document = {
        "tile_types": {"low": {"convex": {"vertices": lower}}, "high": {"convex": {"vertices": upper}}},
        "tiles": [
            {"id": 1, "type": "low", "position": [0, 0, 0]},
            {"id": 2, "type": "high", "position": [0, 0, 0]},
        ],
    }
    structure = parse_structure(document, "slope")
    assert structure.supports == {1: (), 2: (1,)}
    lo, hi = structure.tiles[1], structure.tiles[2]
    assert contacts.shared_face_area(lo, hi) == pytest.approx(a * a * math.sqrt(2))


def _transformed(document: dict, yaw: float, shift: tuple[float, float]) -> dict:
    moved = copy.deepcopy(document)
    c, s = math.cos(yaw), math.sin(yaw)
    for tile in moved["tiles"]:
        x, y, z = tile["position"]
        tile["position"] = [c * x - s * y + shift[0], s * x + c * y + shift[1], z]
        tile["yaw"] = tile.get("yaw", 0.0) + yaw
    for name, (x, y) in moved.get("caches", {}).items():
        moved["caches"][name] = [c * x - s * y + shift[0], s * x + c * y + shift[1]]
    return moved


@pytest.mark.parametrize("name", ["paper_14", "gate_9"])
@pytest.mark.parametrize("yaw", [0.7, -2.3])
def test_rotating_the_whole_structure_keeps_its_relations(name: str, yaw: float) -> None:
    document = yaml.safe_load((STRUCTURES / f"{name}.yaml").read_text())
    original = parse_structure(document, name)
    turned = parse_structure(_transformed(document, yaw, (0.4, -0.25)), name)
    assert turned.supports == original.supports
    assert set(turned.contacts) == set(original.contacts)
    for tile_id, tile in original.tiles.items():
        other = turned.tiles[tile_id]
        assert other.volume == pytest.approx(tile.volume)
        assert polygons.signed_area(other.footprint) == pytest.approx(polygons.signed_area(tile.footprint))
        c, s = math.cos(yaw), math.sin(yaw)
        x, y, z = tile.centroid
        assert np.allclose(other.centroid, [c * x - s * y + 0.4, s * x + c * y - 0.25, z], atol=1e-9)


def test_touching_and_separate_tiles() -> None:
    structure = load_structure(STRUCTURES / "paper_14.yaml")
    touching = set(structure.contacts)
    assert (4, 5) in touching  # octagons side by side
    assert (11, 12) in touching  # long rectangles end to end
    assert (4, 9) not in touching  # 5 mm apart
    assert (13, 14) not in touching


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 1), st.floats(0, 1), st.floats(0, 0.3), st.floats(0.01, 0.2)),
                min_size=2, max_size=25), st.sampled_from([1.0, 1e9]))
def test_candidate_pairs_are_exactly_the_overlapping_boxes_in_sweep_order(
        boxes: list[tuple[float, float, float, float]], spread: float) -> None:
    """Spatial hashing finds what a brute force finds, in the order of a sort and sweep on x (also
    for tiles kilometres apart, where the grid is sparse)."""
    shape = prism_shape(np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float), 1.0)
    tiles = []
    for k, (x, y, z, size) in enumerate(boxes):
        scaled = PlacedTile(k + 1, "box", shape, np.eye(3) * size, np.array([x * spread, y, z]))
        tiles.append(scaled)
    found = contacts.candidate_pairs(tiles, 0.001)
    brute = {
        (i, j)
        for i in range(len(tiles))
        for j in range(i + 1, len(tiles))
        if np.all(tiles[i].aabb[0] - 0.001 <= tiles[j].aabb[1] + 0.001)
        and np.all(tiles[j].aabb[0] - 0.001 <= tiles[i].aabb[1] + 0.001)
    }
    assert set(found) == brute and len(found) == len(brute)
    rank = {int(k): r for r, k in enumerate(np.argsort([t.aabb[0][0] - 0.001 for t in tiles], kind="stable"))}
    assert found == sorted(brute, key=lambda p: (min(rank[p[0]], rank[p[1]]), max(rank[p[0]], rank[p[1]])))


@settings(max_examples=50, deadline=None)
@given(st.integers(5, 14), st.randoms(use_true_random=False))
def test_triangulation_covers_star_polygons(corners: int, rnd) -> None:  # type: ignore[no-untyped-def]
    """Corners sorted by angle about a point outside the polygon can run clockwise: covered too."""
    angles_ = np.sort(np.array([rnd.uniform(0, 2 * math.pi) for _ in range(corners)]))
    if np.min(np.diff(np.concatenate([angles_, [angles_[0] + 2 * math.pi]]))) < 0.05:
        return
    radii = np.array([rnd.uniform(0.3, 1.0) for _ in range(corners)])
    polygon = np.column_stack([radii * np.cos(angles_), radii * np.sin(angles_)])
    if polygons.simplicity_problem(polygon):
        return
    triangles = polygons.triangulate(polygon)
    assert len(triangles) == corners - 2
    total = sum(abs(polygons.signed_area(polygon[list(t)])) for t in triangles)
    assert total == pytest.approx(abs(polygons.signed_area(polygon)))
    assert all(polygons.signed_area(polygon[list(t)]) > 0 for t in triangles)


def test_convex_overlap_area() -> None:
    square = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], float)
    assert polygons.convex_overlap_area(square, square + 0.5) == pytest.approx(0.25)
    assert polygons.convex_overlap_area(square, square + 2.0) == 0.0
    diamond = np.array([[0.5, -0.5], [1.5, 0.5], [0.5, 1.5], [-0.5, 0.5]], float)
    assert polygons.convex_overlap_area(square, diamond) == pytest.approx(1.0)


def test_convex_shape_rejects_interior_points() -> None:
    with pytest.raises(ValueError, match="not corners"):
        convex_shape(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.1, 0.1, 0.1]], float))


def test_cell_keys_are_equal_exactly_for_equal_cells_also_on_a_sparse_grid() -> None:
    dense = np.array([[0, 0, 0], [3, 1, 2], [0, 0, 0], [3, 1, 2], [3, 1, 1]], dtype=np.int64)
    sparse = dense * np.array([2**40, 1, 2**30])  # the grid's size overflows int64
    for cells, shape in ((dense, np.array([4, 2, 3])), (sparse, np.array([2**42, 2, 2**32]))):
        keys = contacts._cell_keys(cells, shape)
        assert [keys[i] == keys[j] for i, j in ((0, 2), (1, 3), (0, 1), (1, 4), (0, 4))] == [
            True, True, False, False, False]


def test_a_clockwise_polygon_is_triangulated_like_its_counter_clockwise_twin() -> None:
    arrow = np.array([[0, 0], [2, 0], [2, 1], [1, 0.4], [0, 1]], float)
    for polygon in (arrow, arrow[::-1].copy()):
        triangles = polygons.triangulate(polygon)
        assert len(triangles) == 3
        assert sum(polygons.signed_area(polygon[list(t)]) for t in triangles) == pytest.approx(1.4)
