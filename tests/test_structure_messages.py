"""Conversion between the structure model and tiling_assembly_msgs/Structure (no middleware)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import STRUCTURES
from rclpy.serialization import deserialize_message, serialize_message

from tiling_assembly.messages import structure_from_msg, structure_to_msg
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.msg import Structure as StructureMsg
from tiling_assembly_msgs.msg import TileType


@pytest.mark.parametrize("name", ["paper_14", "gate_9", "pyramid_91"])
def test_structure_survives_a_trip_through_the_message(name: str) -> None:
    structure = load_structure(STRUCTURES / f"{name}.yaml")
    wire = serialize_message(structure_to_msg(structure))
    back = structure_from_msg(deserialize_message(wire, StructureMsg))
    assert back.name == structure.name and back.frame_id == "map"
    assert back.supports == structure.supports
    assert back.caches.keys() == structure.caches.keys()
    for name_, xy in structure.caches.items():
        assert back.caches[name_] == pytest.approx(xy)
    for tile_id, tile in structure.tiles.items():
        other = back.tiles[tile_id]
        assert other.type_name == tile.type_name
        assert np.allclose(other.vertices, tile.vertices, atol=1e-9)
    for name_, tile_type in structure.tile_types.items():
        assert np.allclose(back.tile_types[name_].attachment_sites, tile_type.attachment_sites)


def test_message_fields_follow_the_shapes() -> None:
    msg = structure_to_msg(load_structure(STRUCTURES / "gate_9.yaml"))
    kinds = {t.name: t.shape for t in msg.tile_types}
    assert kinds["wedge"] == TileType.SHAPE_CONVEX and kinds["beam"] == TileType.SHAPE_PRISM
    beam = next(t for t in msg.tile_types if t.name == "beam")
    assert beam.height == pytest.approx(0.03) and len(beam.vertices) == 4
    tile1 = next(t for t in msg.tiles if t.id == 1)
    q = tile1.pose.orientation
    assert q.z == pytest.approx(np.sin(0.15)) and q.w == pytest.approx(np.cos(0.15))


def test_invalid_message_is_rejected_like_a_file() -> None:
    msg = structure_to_msg(load_structure(STRUCTURES / "paper_14.yaml"))
    msg.tiles[4].pose.position.z += 0.05  # tile 5 lifted off its supports...
    msg.supports = [s for s in msg.supports if s.tile_id != 5]  # ...and no explicit supports
    with pytest.raises(StructureError) as raised:
        structure_from_msg(msg)
    assert raised.value.rule in {"floating", "overlap"}
    msg = structure_to_msg(load_structure(STRUCTURES / "paper_14.yaml"))
    msg.tiles[0].pose.orientation.w = 0.0
    with pytest.raises(StructureError, match="orientation"):
        structure_from_msg(msg)
