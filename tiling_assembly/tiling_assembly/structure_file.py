"""Loading and validating structure files (the contract in DESIGN.md, paper section 2: S_d).

`load_structure(path)` reads a YAML structure file, checks every rule of the contract and returns
a complete Structure, or raises StructureError with one message naming the file, the rule broken
and the tiles involved. Nothing is returned half-loaded.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from tiling_assembly import support
from tiling_assembly.geometry import (
    PlacedTile,
    ShapeError,
    TileShape,
    convex_shape,
    prism_shape,
    rotation_from_rpy,
)
from tiling_assembly.plain_yaml import NOT_PLAIN, read_plain_yaml
from tiling_assembly.structure import Structure, StructureError, TileType

TOP_KEYS = {"name", "frame_id", "tile_types", "tiles", "caches"}
TYPE_KEYS = {"prism", "convex", "attachment_sites"}
PRISM_KEYS = {"polygon", "height"}
CONVEX_KEYS = {"vertices"}
TILE_KEYS = {"id", "type", "position", "yaw", "rpy", "supports"}


# libyaml's parser where PyYAML was built with it: ~10x faster on big structures (same documents)
_SafeLoader: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _StrictLoader(_SafeLoader):  # type: ignore[misc,valid-type]
    """A safe YAML loader that refuses duplicate keys instead of keeping the last one."""


def _mapping_without_duplicates(loader: _StrictLoader, node: yaml.MappingNode) -> dict[Any, Any]:
    seen: dict[Any, int] = {}
    for key_node, _ in node.value:
        key = loader.construct_object(key_node)
        if key in seen:
            raise yaml.constructor.ConstructorError(
                None, None, f"duplicate key '{key}'", key_node.start_mark
            )
        seen[key] = 1
    return loader.construct_mapping(node)


_StrictLoader.add_constructor(
    yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _mapping_without_duplicates
)


class _Checker:
    """Reads one parsed document, raising StructureError at the first broken rule."""

    def __init__(self, source: str) -> None:
        self.source = source
        self.rotations: dict[tuple[float, ...], np.ndarray] = {}  # most tiles share a few turns

    def rotation(self, roll: float, pitch: float, yaw: float) -> np.ndarray:
        """rotation_from_rpy, worked out once per distinct (roll, pitch, yaw); each tile gets its
        own copy. The signs of the angles are part of the key: -0.0 turns to a rotation with -0.0."""
        key = (roll, pitch, yaw, math.copysign(1.0, roll), math.copysign(1.0, pitch), math.copysign(1.0, yaw))
        if key not in self.rotations:
            self.rotations[key] = rotation_from_rpy(roll, pitch, yaw)
        return self.rotations[key].copy()

    def fail(self, rule: str, detail: str, tile_ids: tuple[int, ...] = ()) -> StructureError:
        return StructureError(self.source, rule, detail, tile_ids)

    def keys(self, where: str, value: Any, allowed: set[str], ids: tuple[int, ...] = ()) -> dict[str, Any]:
        if not isinstance(value, Mapping):
            raise self.fail("bad-value", f"{where} must be a mapping, got {_kind(value)}", ids)
        unknown = [] if allowed.issuperset(value) else sorted(str(k) for k in value if k not in allowed)
        if unknown:
            raise self.fail(
                "unknown-key",
                f"{where} has unknown key{'s' if len(unknown) > 1 else ''} "
                f"{', '.join(repr(k) for k in unknown)} (allowed: {', '.join(sorted(allowed))})",
                ids,
            )
        return dict(value)

    def number(self, where: str, value: Any, ids: tuple[int, ...] = ()) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail("bad-value", f"{where} must be a number, got {_kind(value)}", ids)
        if not math.isfinite(value):
            raise self.fail("bad-value", f"{where} must be finite, got {value}", ids)
        return float(value)

    def vector(self, where: str, value: Any, size: int, ids: tuple[int, ...] = ()) -> np.ndarray:
        if not isinstance(value, list) or len(value) != size:
            raise self.fail("bad-value", f"{where} must be a list of {size} numbers, got {_show(value)}", ids)
        if all(type(v) is float and math.isfinite(v) for v in value):
            return np.array(value)  # the common case, without naming every element for an error
        return np.array([self.number(f"{where}[{k}]", v, ids) for k, v in enumerate(value)])

    def points(self, where: str, value: Any, size: int, ids: tuple[int, ...] = ()) -> np.ndarray:
        if not isinstance(value, list) or not value:
            raise self.fail("bad-value", f"{where} must be a non-empty list of points, got {_show(value)}", ids)
        return np.array([self.vector(f"{where}[{k}]", p, size, ids) for k, p in enumerate(value)])

    def tile_type(self, name: Any, spec: Any, users: tuple[int, ...]) -> TileType:
        """Check one tile type; errors name `users`, the ids of the tiles of this type."""
        if not isinstance(name, str) or not name:
            raise self.fail("bad-value", f"tile type names must be non-empty strings, got {_show(name)}")
        where = f"tile type '{name}'"
        try:
            return self._tile_type(name, where, spec)
        except StructureError as error:
            raise StructureError(error.source, error.rule, error.detail, users) from None

    def _tile_type(self, name: str, where: str, spec: Any) -> TileType:
        spec = self.keys(where, spec, TYPE_KEYS)
        kinds = [k for k in ("prism", "convex") if k in spec]
        if len(kinds) != 1:
            raise self.fail("bad-value", f"{where} needs exactly one of 'prism' or 'convex', got {len(kinds)}")
        shape: TileShape
        if kinds[0] == "prism":
            prism = self.keys(f"{where} prism", spec["prism"], PRISM_KEYS)
            missing = sorted(PRISM_KEYS - set(prism))
            if missing:
                raise self.fail("missing-key", f"{where} prism needs '{missing[0]}'")
            polygon = self.points(f"{where} polygon", prism["polygon"], 2)
            height = self.number(f"{where} height", prism["height"])
            if height <= 0:
                raise self.fail("bad-value", f"{where} height must be positive, got {height:g} m")
            try:
                shape = prism_shape(polygon, height)
            except ShapeError as error:
                raise self.fail(error.rule, f"{where}: {error}") from None
        else:
            convex = self.keys(f"{where} convex", spec["convex"], CONVEX_KEYS)
            if "vertices" not in convex:
                raise self.fail("missing-key", f"{where} convex needs 'vertices'")
            vertices = self.points(f"{where} vertices", convex["vertices"], 3)
            try:
                shape = convex_shape(vertices)
            except ShapeError as error:
                raise self.fail(error.rule, f"{where}: {error}") from None
        sites = np.zeros((0, 3))
        if spec.get("attachment_sites") is not None and spec["attachment_sites"] != []:
            sites = self.points(f"{where} attachment_sites", spec["attachment_sites"], 3)
        return TileType(name=name, shape=shape, attachment_sites=sites)

    def tile(self, index: int, spec: Any, types: Mapping[str, TileType]) -> PlacedTile:
        where = f"tiles[{index}]"
        if not isinstance(spec, Mapping):
            raise self.fail("bad-value", f"{where} must be a mapping, got {_kind(spec)}")
        raw_id = spec.get("id")
        if isinstance(raw_id, bool) or not isinstance(raw_id, int) or raw_id <= 0:
            raise self.fail("bad-id", f"{where} needs an 'id' that is a positive integer, got {_show(raw_id)}")
        ids = (raw_id,)
        where = f"tile {raw_id}"
        spec = self.keys(where, spec, TILE_KEYS, ids)
        for key in ("type", "position"):
            if key not in spec:
                raise self.fail("missing-key", f"{where} needs '{key}'", ids)
        type_name = spec["type"]
        if not isinstance(type_name, str) or type_name not in types:
            known = ", ".join(sorted(types)) or "none"
            why = f"{where} has type {_show(type_name)}, not one of the tile types ({known})"
            raise self.fail("unknown-type", why, ids)
        position = self.vector(f"{where} position", spec["position"], 3, ids)
        if "yaw" in spec and "rpy" in spec:
            raise self.fail("bad-value", f"{where} gives both 'yaw' and 'rpy'; give one", ids)
        if "rpy" in spec:
            roll, pitch, yaw = self.vector(f"{where} rpy", spec["rpy"], 3, ids)
        else:
            roll = pitch = 0.0
            yaw = self.number(f"{where} yaw", spec.get("yaw", 0.0), ids)
        explicit = None
        if "supports" in spec and spec["supports"] is not None:
            raw = spec["supports"]
            if not isinstance(raw, list) or any(isinstance(s, bool) or not isinstance(s, int) for s in raw):
                raise self.fail("bad-value", f"{where} supports must be a list of tile ids, got {_show(raw)}", ids)
            explicit = tuple(raw)
        return PlacedTile(
            tile_id=raw_id,
            type_name=type_name,
            shape=types[type_name].shape,
            rotation=self.rotation(roll, pitch, yaw),
            position=position,
            explicit_supports=explicit,
        )


def _kind(value: Any) -> str:
    return {dict: "a mapping", list: "a list", str: "a string", type(None): "nothing"}.get(
        type(value), type(value).__name__
    )


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def parse_structure(
    document: Any, source: str, tolerances: support.Tolerances = support.Tolerances()
) -> Structure:
    """Validate a parsed YAML document and build the Structure (see the module docstring)."""
    check = _Checker(source)
    if not isinstance(document, Mapping):
        why = f"the file must hold a mapping with 'tile_types' and 'tiles', got {_kind(document)}"
        raise check.fail("bad-value", why)
    top = check.keys("the file", document, TOP_KEYS)
    for key in ("tile_types", "tiles"):
        if key not in top:
            raise check.fail("missing-key", f"the file needs '{key}'")
    name = top.get("name", Path(source).stem)
    frame_id = top.get("frame_id", "map")
    for key, value in (("name", name), ("frame_id", frame_id)):
        if not isinstance(value, str) or not value:
            raise check.fail("bad-value", f"'{key}' must be a non-empty string, got {_show(value)}")

    raw_types = top["tile_types"]
    if not isinstance(raw_types, Mapping) or not raw_types:
        raise check.fail("bad-value", f"'tile_types' must be a non-empty mapping, got {_show(raw_types)}")
    raw_tiles = top["tiles"]
    if not isinstance(raw_tiles, list) or not raw_tiles:
        raise check.fail("bad-value", f"'tiles' must be a non-empty list, got {_show(raw_tiles)}")
    users: dict[str, list[int]] = {}
    for spec in raw_tiles:
        if isinstance(spec, Mapping) and isinstance(spec.get("id"), int) and isinstance(spec.get("type"), str):
            users.setdefault(spec["type"], []).append(spec["id"])
    types = {str(n): check.tile_type(n, s, tuple(users.get(str(n), ()))) for n, s in raw_types.items()}
    placed: dict[int, PlacedTile] = {}
    for index, spec in enumerate(raw_tiles):
        tile = check.tile(index, spec, types)
        if tile.tile_id in placed:
            raise check.fail("duplicate-id", f"tile id {tile.tile_id} is used more than once", (tile.tile_id,))
        placed[tile.tile_id] = tile
    placed = dict(sorted(placed.items()))

    caches: dict[str, tuple[float, float]] = {}
    raw_caches = top.get("caches") or {}
    if not isinstance(raw_caches, Mapping):
        raise check.fail("bad-value", f"'caches' must be a mapping of tile type to [x, y], got {_show(raw_caches)}")
    for type_name, xy in raw_caches.items():
        if type_name not in types:
            raise check.fail("unknown-type", f"cache for {_show(type_name)}, which is not a tile type")
        x, y = check.vector(f"cache of '{type_name}'", xy, 2)
        caches[str(type_name)] = (float(x), float(y))

    supports, touching = support.derive_supports(placed, source, tolerances)
    support.check_attachment_sites(
        placed,
        {n: t.attachment_sites for n, t in types.items()},
        supports,
        source,
        tolerances.contact,
    )
    return Structure(
        name=name,
        frame_id=frame_id,
        tile_types=types,
        tiles=placed,
        supports=supports,
        caches=caches,
        contacts=tuple(touching),
        source=source,
    )


def load_structure(path: str | Path, tolerances: support.Tolerances = support.Tolerances()) -> Structure:
    """Read, validate and build the structure in `path` (see the module docstring)."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except UnicodeDecodeError as error:
        raise StructureError(source, "file", f"not UTF-8 text (byte {error.start})") from None
    except OSError as error:
        raise StructureError(source, "file", f"cannot read the file: {error.strerror or error}") from None
    document = read_plain_yaml(text)  # the plain YAML of structure files, 5x faster than PyYAML
    if document is NOT_PLAIN:
        document = _read_yaml(text, source)
    return parse_structure(document, source, tolerances)


def _read_yaml(text: str, source: str) -> Any:
    """The document in `text` read by PyYAML, which reports whatever is wrong with it."""
    try:
        return yaml.load(text, Loader=_StrictLoader)
    except yaml.YAMLError as error:
        mark = getattr(error, "problem_mark", None) or getattr(error, "context_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark else ""
        problem = getattr(error, "problem", None) or str(error).splitlines()[0]
        raise StructureError(source, "yaml", f"not valid YAML{where}: {problem}") from None
