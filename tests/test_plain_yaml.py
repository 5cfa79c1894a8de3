"""The fast reader of plain YAML reads what PyYAML reads, or leaves the text to PyYAML."""

from __future__ import annotations

import json
import random
from typing import Any

import pytest
import yaml
from conftest import DATA, REPO

from planner_node.structure_generators import GENERATORS
from tiling_assembly.plain_yaml import NOT_PLAIN, read_plain_yaml
from tiling_assembly.structure_file import _StrictLoader

YAML_FILES = sorted((REPO / "config").rglob("*.yaml")) + sorted((DATA / "structures").rglob("*.yaml"))
TEXTS = [p.read_bytes().decode("utf-8", errors="replace") for p in YAML_FILES]

PLAIN = [
    "a: 1",
    "a:\n- 1\n- 2\nb: 3",
    "- - 1\n  - 2\n- 3",
    "a: [1, [2, 3], {b: c}]",
    "a:\n  b:\n  c: 1",
    "- a:\n  - b\n  c: 1",
    "a: yes\nb: Off\nc: ~\nd: null\ne: 'x y'\nf: \"q\"",
    "a: -0\nb: +1\nc: -0.0\nd: 1.0e-05\ne: 0.",
    "a: [1,2]",
    "a: {b: [1]}",
    "-\n  - a",
    "a:    # c\n  - 1  # d\n",
    "- a: 1\n  b: 2\n- c: 3",
]
NOT_READ_HERE = [
    "a: {b: 1, b: 2}",  # duplicate keys: the strict loader's error
    "a: 1\na: 2",
    "x: 012",  # octal, 1e5 a string, 1_000 a number: PyYAML's
    "y: 1e5",
    "a: {b:1}",
    "? a\n: b",
    "a: &x 1\nb: *x",
    "a: !!str 1",
    "a: |\n  t",
    "a: b\n  c",
    "- a\n - b",
    "[1, 2]",
    "a: [1, 2,]",
    "a: 1\n---\nb: 2",
    "a: 'it''s'",
    "a: b: c",
    "a: [1,\n  2]",
    "a:\tb",
    "",
]


def same(a: Any, b: Any) -> bool:
    """Equal with equal types all the way down (1 == 1.0 == True in Python, not in YAML)."""
    if type(a) is not type(b):
        return False
    if isinstance(a, dict):
        return list(a) == list(b) and all(same(x, y) for x, y in zip(a, b, strict=True)) and all(
            same(a[k], b[k]) for k in a
        )
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b) and repr(a) == repr(b)


def _agrees_with_pyyaml(text: str) -> bool:
    """True when read here (and then as PyYAML reads it); False when left to PyYAML."""
    mine = read_plain_yaml(text)
    if mine is NOT_PLAIN:
        return False
    assert same(mine, yaml.load(text, Loader=_StrictLoader)), text
    return True


@pytest.mark.parametrize("text", PLAIN)
def test_plain_yaml_is_read_as_pyyaml_reads_it(text: str) -> None:
    assert _agrees_with_pyyaml(text)


@pytest.mark.parametrize("text", NOT_READ_HERE)
def test_anything_else_is_left_to_pyyaml(text: str) -> None:
    assert read_plain_yaml(text) is NOT_PLAIN


@pytest.mark.parametrize("text", TEXTS, ids=[p.name for p in YAML_FILES])
def test_the_repositorys_files_read_as_pyyaml_reads_them(text: str) -> None:
    try:
        _agrees_with_pyyaml(text)
    except yaml.YAMLError:
        assert read_plain_yaml(text) is NOT_PLAIN  # malformed on purpose


@pytest.mark.parametrize("kind", sorted(GENERATORS))
def test_generated_structures_in_block_style_are_read_here(kind: str) -> None:
    document = json.loads(json.dumps(GENERATORS[kind](300), default=float))  # numpy numbers as floats
    assert _agrees_with_pyyaml(yaml.safe_dump(document))


def test_damaged_texts_are_read_as_pyyaml_reads_them_or_left_to_it() -> None:
    """Random edits of small documents: whatever is read here, PyYAML reads the same way."""
    rng = random.Random(5)
    seeds = PLAIN + [text for text in TEXTS if len(text) < 3000][:20]
    pieces = [*" -:#[]{},'\"\n01.aeyn~_", "  ", "- ", ": ", "\n  ", "\n- "]
    read_here = 0
    for _ in range(20000):
        text = list(rng.choice(seeds))
        for _ in range(rng.randint(1, 4)):
            if not text:
                break
            k = rng.randrange(len(text))
            edit = rng.random()
            if edit < 0.4:
                del text[k]
            elif edit < 0.8:
                text.insert(k, rng.choice(pieces))
            else:
                text[k] = rng.choice(pieces)
        try:
            read_here += _agrees_with_pyyaml("".join(text))
        except yaml.YAMLError:
            pytest.fail(f"read here, but PyYAML refuses it: {''.join(text)!r}")
    assert read_here > 1000
