"""The structure model: tile types, placed tiles, parts caches and the support relation.

S_d in the paper's notation (section 2): what is to be built, with the precedence constraints
(section 2.1) given by which tile rests on which. Instances are immutable and complete: they are
only made by the loader (tiling_assembly.structure_file) or the message conversion, both of which
validate everything first, so a Structure is never half-loaded.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from tiling_assembly.geometry import PlacedTile, TileShape

if TYPE_CHECKING:
    import networkx as nx

Array = NDArray[np.float64]


def topological_order(supports: Mapping[int, Iterable[int]]) -> list[int] | None:
    """Every tile after its supports, or None when the supports form a cycle.

    Without networkx: importing it costs a tenth of a second, a third of what loading a 10,000-tile
    structure now costs in all."""
    waiting = {tile: len(set(below)) for tile, below in supports.items()}
    resting_on: dict[int, list[int]] = {tile: [] for tile in supports}
    for tile, below in supports.items():
        for support in set(below):
            resting_on.setdefault(support, []).append(tile)
    ready = sorted(tile for tile, count in waiting.items() if count == 0)
    order: list[int] = []
    while ready:
        tile = ready.pop()
        order.append(tile)
        for above in resting_on.get(tile, ()):
            waiting[above] -= 1
            if waiting[above] == 0:
                ready.append(above)
    return order if len(order) == len(waiting) else None


class StructureError(ValueError):
    """A structure that breaks a rule; the message names the source, the rule and the tiles."""

    def __init__(
        self, source: str, rule: str, detail: str, tile_ids: Iterable[int] = (), more: int = 0
    ) -> None:
        self.source = source
        self.rule = rule
        self.detail = detail
        self.tile_ids = tuple(sorted(set(int(t) for t in tile_ids)))
        self.more = more
        tiles = ""
        if self.tile_ids:
            word = "tile" if len(self.tile_ids) == 1 else "tiles"
            tiles = f" [{word} {', '.join(str(t) for t in self.tile_ids)}]"
        extra = f" (and {more} more problem{'s' if more > 1 else ''} of this kind)" if more else ""
        super().__init__(f"{source}: {rule}{tiles}: {detail}{extra}")


@dataclass(frozen=True, eq=False)
class TileType:
    """A kind of tile: its shape and attachment sites (tile frame, metres)."""

    name: str
    shape: TileShape
    attachment_sites: Array = field(default_factory=lambda: np.zeros((0, 3)))


@dataclass(frozen=True, eq=False)
class Structure:
    """A validated structure with its support relation."""

    name: str
    frame_id: str
    tile_types: Mapping[str, TileType]
    tiles: Mapping[int, PlacedTile]  # by id, in increasing id order
    supports: Mapping[int, tuple[int, ...]]  # tile id -> ids of the tiles it rests on
    caches: Mapping[str, tuple[float, float]]  # tile type -> (x, y) of its parts cache
    contacts: tuple[tuple[int, int], ...] = ()  # pairs of touching tiles (a < b)
    source: str = "<memory>"
    whole: Structure | None = None  # what a subset was cut from: all its tiles stand where no robot base can

    @property
    def site(self) -> Structure:
        """The whole structure this one is part of (itself unless a subset)."""
        return self.whole if self.whole is not None else self

    @property
    def tile_ids(self) -> list[int]:
        return list(self.tiles)

    def __len__(self) -> int:
        return len(self.tiles)

    @cached_property
    def supported_by(self) -> dict[int, tuple[int, ...]]:
        """Inverse of `supports`: tile id -> ids of the tiles resting on it."""
        children: dict[int, list[int]] = {i: [] for i in self.tiles}
        for tile, below in self.supports.items():
            for s in below:
                children[s].append(tile)
        return {i: tuple(sorted(c)) for i, c in children.items()}

    @cached_property
    def resting_above(self) -> dict[int, frozenset[int]]:
        """Tile id -> ids of the tiles resting on it, directly or through others."""
        above: dict[int, frozenset[int]] = {}
        for tile in reversed(topological_order(self.supports) or []):  # the top first
            on_it = self.supported_by[tile]
            above[tile] = frozenset(on_it).union(*(above[t] for t in on_it))
        return above

    @cached_property
    def precedence(self) -> nx.DiGraph:
        """The precedence DAG: an edge s -> t when tile s must be placed before tile t."""
        import networkx as nx

        graph = nx.DiGraph()
        graph.add_nodes_from(self.tiles)
        graph.add_edges_from((s, t) for t, below in self.supports.items() for s in below)
        return graph

    @cached_property
    def layers(self) -> dict[int, int]:
        """Layer of every tile: 0 on the floor, else one above its highest support."""
        layer: dict[int, int] = {}
        for tile in topological_order(self.supports) or ():  # a Structure's supports form no cycle
            below = self.supports[tile]
            layer[tile] = 1 + max(layer[s] for s in below) if below else 0
        return layer

    def tiles_by_layer(self) -> list[list[int]]:
        """Tile ids grouped by layer, bottom first."""
        if not self.tiles:
            return []
        grouped: list[list[int]] = [[] for _ in range(max(self.layers.values()) + 1)]
        for tile, layer in sorted(self.layers.items()):
            grouped[layer].append(tile)
        return grouped

    def cache_position(self, type_name: str) -> tuple[float, float] | None:
        return self.caches.get(type_name)

    @cached_property
    def bounds(self) -> tuple[Array, Array]:
        """Axis-aligned bounding box of the whole structure (min corner, max corner)."""
        if not self.tiles:
            return np.zeros(3), np.zeros(3)
        lows = np.array([t.aabb[0] for t in self.tiles.values()])
        highs = np.array([t.aabb[1] for t in self.tiles.values()])
        return lows.min(axis=0), highs.max(axis=0)

    def subset(self, keep: Iterable[int]) -> Structure:
        """The structure restricted to `keep` (supports outside it dropped), e.g. S_a so far."""
        ids = sorted(set(keep) & set(self.tiles))
        chosen = set(ids)
        return Structure(
            name=self.name,
            frame_id=self.frame_id,
            tile_types=self.tile_types,
            tiles={i: self.tiles[i] for i in ids},
            supports={i: tuple(s for s in self.supports[i] if s in chosen) for i in ids},
            caches=self.caches,
            contacts=tuple((a, b) for a, b in self.contacts if a in chosen and b in chosen),
            source=self.source,
            whole=self.site,
        )
