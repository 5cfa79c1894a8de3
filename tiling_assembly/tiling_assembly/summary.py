"""A readable text summary of a structure: its tile types, layers and support relation."""

from __future__ import annotations

import numpy as np

from tiling_assembly.structure import Structure, TileType


def _describe_type(tile_type: TileType) -> str:
    shape = tile_type.shape
    extent = shape.vertices.max(axis=0) - shape.vertices.min(axis=0)
    size = " x ".join(f"{v * 100:.1f}" for v in extent) + " cm"
    if shape.kind == "prism":
        assert shape.polygon is not None
        what = f"prism, {len(shape.polygon)}-gon"
    else:
        what = f"convex polytope, {len(shape.vertices)} vertices, {len(shape.faces)} faces"
    sites = len(tile_type.attachment_sites)
    return f"{what}, {size}" + (f", {sites} attachment site{'s' if sites != 1 else ''}" if sites else "")


def summarize(structure: Structure) -> str:
    """Multi-line summary: header, tile types, tiles by layer, supports."""
    layers = structure.tiles_by_layer()
    lo, hi = structure.bounds
    lines = [
        f"Structure '{structure.name}' from {structure.source}",
        f"  {len(structure)} tiles of {len(structure.tile_types)} types in {len(layers)} layers, "
        f"frame '{structure.frame_id}', "
        f"extent {(hi[0] - lo[0]) * 100:.1f} x {(hi[1] - lo[1]) * 100:.1f} x {(hi[2] - lo[2]) * 100:.1f} cm",
        "",
        "Tile types:",
    ]
    width = max(len(n) for n in structure.tile_types)
    for name, tile_type in structure.tile_types.items():
        count = sum(1 for t in structure.tiles.values() if t.type_name == name)
        cache = structure.caches.get(name)
        where = f", cache at ({cache[0]:.2f}, {cache[1]:.2f}) m" if cache else ""
        lines.append(f"  {name:<{width}}  x{count:<3} {_describe_type(tile_type)}{where}")
    lines += ["", "Tiles by layer (bottom first):"]
    for k, ids in enumerate(layers):
        shown = ", ".join(f"{i} {structure.tiles[i].type_name}" for i in ids)
        lines.append(f"  layer {k}: {shown}")
    lines += ["", "Support relation (tile <- the tiles it rests on):"]
    for tile_id, tile in structure.tiles.items():
        below = structure.supports[tile_id]
        centre = np.where(np.abs(tile.centroid) < 5e-4, 0.0, tile.centroid)
        rests = ", ".join(str(s) for s in below) if below else "floor"
        yaw = np.degrees(tile.yaw)
        lines.append(
            f"  {tile_id:>4} {tile.type_name:<{width}} at ({centre[0]:+.3f}, {centre[1]:+.3f}, "
            f"{centre[2]:+.3f}) m, yaw {yaw:+6.1f} deg  <- {rests}"
        )
    return "\n".join(lines)
