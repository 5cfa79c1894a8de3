"""The support relation and the physical rules of a structure (paper section 2.1).

"Precedence constraints, specified by structural stability requirements": tile j supports tile i
when j's top touches i's bottom over more than a small area; a tile on the floor needs no support.
Explicit supports in a structure file replace the derived ones for that tile. This module also
enforces the rules a buildable structure obeys: no tile below the floor, no two tiles
interpenetrating, no floating tile, no support cycle, and attachment sites that meet.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from tiling_assembly import contacts, polygons
from tiling_assembly.geometry import PlacedTile
from tiling_assembly.structure import StructureError, topological_order


@dataclass(frozen=True)
class Tolerances:
    """Geometric tolerances of the rules (metres and square metres)."""

    contact: float = contacts.CONTACT_TOLERANCE
    overlap: float = contacts.OVERLAP_TOLERANCE
    min_support_area: float = contacts.MIN_SUPPORT_AREA


def _fail(source: str, rule: str, problems: list[tuple[list[int], str]]) -> None:
    if problems:
        ids, detail = problems[0]
        raise StructureError(source, rule, detail, ids, more=len(problems) - 1)


def derive_supports(
    tiles: Mapping[int, PlacedTile],
    source: str,
    tolerances: Tolerances = Tolerances(),
) -> tuple[dict[int, tuple[int, ...]], list[tuple[int, int]]]:
    """Check the geometry and derive the support relation (section 2.1's precedence constraints).

    Returns (supports, touching pairs). Explicit supports (`PlacedTile.explicit_supports`) are
    taken as given for their tile after checking that they exist and form no cycle.
    Raises StructureError naming the first broken rule.
    """
    ordered = list(tiles.values())
    boxes = contacts.Boxes.of(ordered)
    _check_above_floor(ordered, source=source, tolerances=tolerances)
    found = contacts.find_contacts(ordered, tolerances.contact, boxes)
    _check_no_overlap(found, source=source, tolerances=tolerances)
    derived = _supports_from_contacts(ordered, found=found, boxes=boxes, tolerances=tolerances)
    on_floor = contacts.on_the_floor(
        ordered, boxes=boxes, plane_tolerance=tolerances.contact, min_area=tolerances.min_support_area)
    _check_explicit_supports_exist(tiles, source=source)
    supports = _choose_supports(tiles, derived=derived, on_floor=on_floor)
    _check_nothing_floating(tiles, supports=supports, on_floor=on_floor, source=source)
    _check_no_support_cycle(tiles, supports=supports, source=source)
    return supports, found.id_pairs()


def _check_above_floor(ordered: list[PlacedTile], *, source: str, tolerances: Tolerances) -> None:
    _fail(
        source,
        "below-floor",
        [
            ([t.tile_id], f"tile {t.tile_id} reaches {t.aabb[0][2] * 1000:.1f} mm below the floor (z = 0)")
            for t in ordered
            if t.aabb[0][2] < -tolerances.contact
        ],
    )


def _check_no_overlap(found: contacts.Contacts, *, source: str, tolerances: Tolerances) -> None:
    overlapping = np.flatnonzero(found.separation < -tolerances.overlap).tolist()
    _fail(
        source,
        "overlap",
        [
            ([a, b], f"tiles {a} and {b} overlap by {-depth * 1000:.1f} mm")
            for a, b, depth in zip(found.a[overlapping].tolist(), found.b[overlapping].tolist(),
                                   found.separation[overlapping].tolist(), strict=True)
        ],
    )


def _supports_from_contacts(
    ordered: list[PlacedTile], *, found: contacts.Contacts, boxes: contacts.Boxes, tolerances: Tolerances
) -> dict[int, set[int]]:
    """For every tile, the touching tiles whose top meets its bottom over more than a small area."""
    derived: dict[int, set[int]] = {t.tile_id: set() for t in ordered}
    for lower, upper in contacts.resting_pairs(ordered, found, boxes=boxes, plane_tolerance=tolerances.contact,
                                               min_area=tolerances.min_support_area):
        derived[upper].add(lower)
    return derived


def _check_explicit_supports_exist(tiles: Mapping[int, PlacedTile], *, source: str) -> None:
    unknown = []
    for i, t in tiles.items():
        for s in t.explicit_supports or ():
            if s == i:
                unknown.append(([i], f"tile {i} lists itself as its own support"))
            elif s not in tiles:
                unknown.append(([i], f"tile {i} lists support {s}, which is not a tile of the structure"))
    _fail(source, "unknown-support", unknown)


def _choose_supports(
    tiles: Mapping[int, PlacedTile], *, derived: Mapping[int, set[int]], on_floor: set[int]
) -> dict[int, tuple[int, ...]]:
    """Explicit supports where given; otherwise none on the floor, else the derived ones."""
    supports: dict[int, tuple[int, ...]] = {}
    for i, t in tiles.items():
        if t.explicit_supports is not None:
            supports[i] = tuple(sorted(set(t.explicit_supports)))
        elif i in on_floor:
            supports[i] = ()
        else:
            supports[i] = tuple(sorted(derived[i]))
    return supports


def _check_nothing_floating(
    tiles: Mapping[int, PlacedTile],
    *,
    supports: Mapping[int, tuple[int, ...]],
    on_floor: set[int],
    source: str,
) -> None:
    _fail(
        source,
        "floating",
        [
            ([i], f"tile {i} rests on nothing: its bottom is {tiles[i].aabb[0][2] * 1000:.1f} mm above "
                  "the floor and no tile below it shares a face with it")
            for i in tiles
            if not supports[i] and i not in on_floor
        ],
    )


def _check_no_support_cycle(
    tiles: Mapping[int, PlacedTile], *, supports: Mapping[int, tuple[int, ...]], source: str
) -> None:
    if topological_order(supports) is not None:
        return
    import networkx as nx

    graph = nx.DiGraph()
    graph.add_nodes_from(tiles)
    graph.add_edges_from((s, i) for i, below in supports.items() for s in below)
    ids = [u for u, _ in nx.find_cycle(graph)]
    chain = " -> ".join(str(u) for u in [*ids, ids[0]])
    _fail(source, "support-cycle", [(ids, f"the supports form a cycle: {chain}")])


def _point_on_face(point: np.ndarray, tile: PlacedTile, tolerance: float) -> bool:
    for k, (n, d) in enumerate(zip(tile.face_normals, tile.face_offsets, strict=True)):
        if abs(n @ point - d) > tolerance:
            continue
        u, v = contacts.plane_basis(n)
        corners = tile.face_corners(k)
        flat = np.column_stack([corners @ u, corners @ v])
        if polygons.point_in_polygon(np.array([point @ u, point @ v]), flat, tolerance):
            return True
    return False


def world_sites(tile: PlacedTile, sites: np.ndarray) -> np.ndarray:
    """Attachment sites of a tile in the structure frame."""
    return sites @ tile.rotation.T + tile.position if len(sites) else np.zeros((0, 3))


def check_attachment_sites(
    tiles: Mapping[int, PlacedTile],
    sites_of_type: Mapping[str, np.ndarray],
    supports: Mapping[int, tuple[int, ...]],
    source: str,
    tolerance: float = contacts.CONTACT_TOLERANCE,
) -> None:
    """Where attachment sites are given, a supported tile and each support must be joined by one.

    Sites must lie on their own tile's surface; for every support pair (j under i) where either
    type has sites, some site of i must lie on a face of j or some site of j on a face of i (a
    site meeting a site is a special case of both).
    """
    _check_sites_on_surface(tiles, sites_of_type=sites_of_type, source=source, tolerance=tolerance)
    _check_supports_joined(tiles, sites_of_type=sites_of_type, supports=supports, source=source, tolerance=tolerance)


def _check_sites_on_surface(
    tiles: Mapping[int, PlacedTile], *, sites_of_type: Mapping[str, np.ndarray], source: str, tolerance: float
) -> None:
    # one tile of a type is enough: every tile of the type carries the same sites in its own frame
    off_surface = []
    for name, sites in sites_of_type.items():
        example = next((t for t in tiles.values() if t.type_name == name), None)
        if example is None:
            continue
        for k, site in enumerate(world_sites(example, sites)):
            if not _point_on_face(site, example, tolerance):
                users = [t.tile_id for t in tiles.values() if t.type_name == name]
                off_surface.append(
                    (users, f"attachment site {k} of tile type '{name}' "
                         f"({', '.join(f'{c:g}' for c in sites[k])}) is not on the tile's surface")
                )
    _fail(source, "attachment", off_surface)


def _check_supports_joined(
    tiles: Mapping[int, PlacedTile],
    *,
    sites_of_type: Mapping[str, np.ndarray],
    supports: Mapping[int, tuple[int, ...]],
    source: str,
    tolerance: float,
) -> None:
    if not any(len(sites) for sites in sites_of_type.values()):
        return  # no tile type has sites: nothing to join
    unmet = []
    for i, below in supports.items():
        upper = tiles[i]
        upper_sites = world_sites(upper, sites_of_type.get(upper.type_name, np.zeros((0, 3))))
        for j in below:
            lower = tiles[j]
            lower_sites = world_sites(lower, sites_of_type.get(lower.type_name, np.zeros((0, 3))))
            if len(upper_sites) == 0 and len(lower_sites) == 0:
                continue
            if any(_point_on_face(p, lower, tolerance) for p in upper_sites) or any(
                _point_on_face(p, upper, tolerance) for p in lower_sites
            ):
                continue
            unmet.append(([i, j], f"no attachment site joins tile {i} to its support {j}"))
    _fail(source, "attachment", unmet)
