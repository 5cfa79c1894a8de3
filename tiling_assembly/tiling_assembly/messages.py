"""Conversion between the structure model and `tiling_assembly_msgs/Structure`.

The only module of the core that imports ROS message types. A structure received as a message is
validated by the same rules as a structure file (it goes through `parse_structure`), with the
message's support relation taken as explicit.
"""

from __future__ import annotations

from typing import Any

from geometry_msgs.msg import Point, Pose

from tiling_assembly.geometry import PlacedTile, rotation_from_quaternion, rpy_from_rotation
from tiling_assembly.structure import Structure, StructureError
from tiling_assembly.structure_file import parse_structure
from tiling_assembly_msgs.msg import PartsCache, SupportRelation, Tile, TileType
from tiling_assembly_msgs.msg import Structure as StructureMsg


def pose_of(tile: PlacedTile) -> Pose:
    """The tile frame's pose in the structure frame."""
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in tile.position)
    q = tile.quaternion
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = q
    return pose


def _point(xyz: Any) -> Point:
    return Point(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2]) if len(xyz) > 2 else 0.0)


def structure_to_msg(structure: Structure) -> StructureMsg:
    """The message for a structure (header.stamp left for the publisher to set)."""
    msg = StructureMsg()
    msg.header.frame_id = structure.frame_id
    msg.name = structure.name
    for name, tile_type in structure.tile_types.items():
        shape = tile_type.shape
        out = TileType(name=name)
        if shape.kind == "prism":
            assert shape.polygon is not None
            out.shape = TileType.SHAPE_PRISM
            out.vertices = [_point(p) for p in shape.polygon]
            out.height = shape.height
        else:
            out.shape = TileType.SHAPE_CONVEX
            out.vertices = [_point(p) for p in shape.vertices]
        out.attachment_sites = [_point(p) for p in tile_type.attachment_sites]
        msg.tile_types.append(out)
    for tile_id, tile in structure.tiles.items():
        msg.tiles.append(Tile(id=tile_id, type=tile.type_name, pose=pose_of(tile)))
        msg.supports.append(
            SupportRelation(tile_id=tile_id, support_ids=list(structure.supports[tile_id]))
        )
    for name, (x, y) in structure.caches.items():
        msg.caches.append(PartsCache(tile_type=name, position=Point(x=x, y=y, z=0.0)))
    return msg


def structure_from_msg(msg: StructureMsg, source: str = "structure message") -> Structure:
    """Validate a structure message and build the model (raises StructureError)."""
    types: dict[str, Any] = {}
    for t in msg.tile_types:
        sites = [[p.x, p.y, p.z] for p in t.attachment_sites]
        if t.shape == TileType.SHAPE_PRISM:
            spec: dict[str, Any] = {
                "prism": {"polygon": [[p.x, p.y] for p in t.vertices], "height": t.height}
            }
        else:
            spec = {"convex": {"vertices": [[p.x, p.y, p.z] for p in t.vertices]}}
        if sites:
            spec["attachment_sites"] = sites
        types[t.name] = spec
    explicit = {s.tile_id: [int(i) for i in s.support_ids] for s in msg.supports}
    tiles = []
    for t in msg.tiles:
        q = t.pose.orientation
        try:
            rotation = rotation_from_quaternion(q.x, q.y, q.z, q.w)
        except ValueError as error:
            raise StructureError(source, "bad-value", f"tile {t.id} orientation: {error}", [t.id]) from None
        roll, pitch, yaw = rpy_from_rotation(rotation)
        entry: dict[str, Any] = {
            "id": int(t.id),
            "type": t.type,
            "position": [t.pose.position.x, t.pose.position.y, t.pose.position.z],
            "rpy": [roll, pitch, yaw],
        }
        if t.id in explicit:
            entry["supports"] = explicit[t.id]
        tiles.append(entry)
    document: dict[str, Any] = {
        "name": msg.name or "structure",
        "frame_id": msg.header.frame_id or "map",
        "tile_types": types,
        "tiles": tiles,
    }
    if msg.caches:
        document["caches"] = {c.tile_type: [c.position.x, c.position.y] for c in msg.caches}
    return parse_structure(document, source)
