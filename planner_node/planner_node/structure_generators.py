"""Structures of any size for benchmarks and tests: walls, pyramids, bridges and random clusters.

Each generator returns a structure document in the format of the structure-file contract
(DESIGN.md), to be validated by `tiling_assembly.structure_file.parse_structure` like any file.
Sizes are approximate (the shapes come in whole courses); `len(document["tiles"])` is exact.
Parts caches stand on a circle 1 m outside the structure, one per tile type.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

Document = dict[str, Any]

CUBE = 0.05  # m, edge of the cube blocks
CACHE_MARGIN = 1.0  # m, from the structure's outline to the caches


def _box(length: float, width: float, height: float) -> dict[str, Any]:
    hx, hy = length / 2, width / 2
    return {"prism": {"polygon": [[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]], "height": height}}


def _document(name: str, types: dict[str, Any], tiles: list[tuple[str, float, float, float]]) -> Document:
    xy = np.array([[x, y] for _, x, y, _ in tiles])
    centre = (xy.min(axis=0) + xy.max(axis=0)) / 2
    radius = float(np.max(np.linalg.norm(xy - centre, axis=1))) + CACHE_MARGIN
    caches = {}
    for k, type_name in enumerate(types):
        angle = -math.pi / 2 + 2 * math.pi * k / len(types)
        caches[type_name] = [round(centre[0] + radius * math.cos(angle), 4),
                             round(centre[1] + radius * math.sin(angle), 4)]
    return {
        "name": name,
        "frame_id": "map",
        "tile_types": types,
        "tiles": [
            {"id": k, "type": t, "position": [round(x, 6), round(y, 6), round(z, 6)]}
            for k, (t, x, y, z) in enumerate(tiles, start=1)
        ],
        "caches": caches,
    }


def wall(n: int) -> Document:
    """A single-thickness running-bond brick wall about three times as long as high."""
    length, depth, height = 0.16, 0.08, 0.04
    courses = max(2, round(math.sqrt(2 * n / 6)))
    bricks = max(2, round((2 * n / courses - 1) / 2))
    tiles = []
    for c in range(courses):
        z = c * height
        if c % 2 == 0:
            tiles += [("brick", i * length, 0.0, z) for i in range(bricks)]
        else:
            tiles.append(("half_brick", -length / 4, 0.0, z))
            tiles += [("brick", (i + 0.5) * length, 0.0, z) for i in range(bricks - 1)]
            tiles.append(("half_brick", (bricks - 0.75) * length, 0.0, z))
    types = {"brick": _box(length, depth, height), "half_brick": _box(length / 2, depth, height)}
    return _document(f"wall_{len(tiles)}", types, tiles)


def pyramid(n: int) -> Document:
    """A stepped square pyramid of cubes, every upper cube resting on four (two alternating types)."""
    base = 1
    while sum((base - k) ** 2 for k in range(base)) < n:
        base += 1
    tiles = []
    for k in range(base):
        side = base - k
        for i in range(side):
            for j in range(side):
                kind = "block_a" if k % 2 == 0 else "block_b"
                tiles.append((kind, (i + k / 2) * CUBE, (j + k / 2) * CUBE, k * CUBE))
    types = {"block_a": _box(CUBE, CUBE, CUBE), "block_b": _box(CUBE, CUBE, CUBE)}
    return _document(f"pyramid_{len(tiles)}", types, tiles)


def bridge(n: int) -> Document:
    """An arcade: rows of cube piers carrying a deck of planks, each plank spanning two piers."""
    rows, pier_height = (2, 4) if n < 500 else (5, 4) if n < 5000 else (25, 6)
    per_span = rows * pier_height + 2 * rows  # one pier and two deck courses per span
    spans = max(2, round((n - rows * pier_height + rows) / per_span))
    pitch = 4 * CUBE
    plank = (pitch, CUBE, CUBE / 2)
    tiles = []
    for y in range(rows):
        for i in range(spans + 1):
            tiles += [("pier_block", i * pitch, y * CUBE, z * CUBE) for z in range(pier_height)]
    deck = pier_height * CUBE
    for y in range(rows):
        tiles += [("plank", (i + 0.5) * pitch, y * CUBE, deck) for i in range(spans)]
        tiles += [("plank", (i + 1) * pitch, y * CUBE, deck + plank[2]) for i in range(spans - 1)]
    types = {"pier_block": _box(CUBE, CUBE, CUBE), "plank": _box(*plank)}
    return _document(f"bridge_{len(tiles)}", types, tiles)


def random_cluster(n: int, seed: int = 0) -> Document:
    """Random mounds of stacked cubes (possibly separate), some capped by planks across two columns."""
    rng = np.random.default_rng(seed)
    clusters = max(1, n // 150)
    side = max(4, math.ceil(math.sqrt(n / 2.5)))
    heights = np.zeros((side, side), dtype=int)
    cells = np.stack(np.meshgrid(np.arange(side), np.arange(side), indexing="ij"), axis=-1)
    while heights.sum() < 0.85 * n:
        centre = rng.uniform(0, side, size=2)
        radius = rng.uniform(1.5, max(2.0, side / math.sqrt(clusters)))
        peak = rng.integers(2, 7)
        r = np.linalg.norm(cells + 0.5 - centre, axis=-1)
        mound = np.where(r < radius, np.ceil(peak * (1 - r / radius)), 0).astype(int)
        heights = np.maximum(heights, mound)
    # trim random columns from the top until the cubes alone do not exceed n
    while heights.sum() > n:
        filled = np.argwhere(heights > 0)
        i, j = filled[rng.integers(len(filled))]
        heights[i, j] -= 1
    tiles = []
    for (i, j), h in np.ndenumerate(heights):
        tiles += [("block", i * CUBE, j * CUBE, z * CUBE) for z in range(h)]
    used = np.zeros_like(heights, dtype=bool)
    for i, j in rng.permutation(np.argwhere(heights > 0)):
        if len(tiles) >= n:
            break
        if used[i, j] or i + 1 >= side or used[i + 1, j] or heights[i + 1, j] != heights[i, j]:
            continue
        used[i, j] = used[i + 1, j] = True
        tiles.append(("plank", (i + 0.5) * CUBE, j * CUBE, heights[i, j] * CUBE))
    types = {"block": _box(CUBE, CUBE, CUBE), "plank": _box(2 * CUBE, CUBE, CUBE / 2)}
    return _document(f"cluster_{len(tiles)}_s{seed}", types, tiles)


GENERATORS: dict[str, Callable[[int], Document]] = {
    "wall": wall,
    "pyramid": pyramid,
    "bridge": bridge,
    "cluster": random_cluster,
}
