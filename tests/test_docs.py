"""The documentation in docs/ names everything the code offers (drift check; no ROS, no build).

Every name is taken from the code itself: the console_scripts of every package's setup.py, the
launch files on disk, the key sets of the structure-file parser (read from its source, and checked
against the example structures) and the topic and service constants of tiling_sim's
sim_interface.py.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest
import yaml

REPO = Path(__file__).resolve().parent.parent
DOCS = REPO / "docs"
STRUCTURE_FILE_PARSER = REPO / "tiling_assembly" / "tiling_assembly" / "structure_file.py"
SIM_INTERFACE = REPO / "tiling_sim" / "tiling_sim" / "sim_interface.py"
SETUP_FILES = sorted(p for p in REPO.glob("*/setup.py"))
LAUNCH_FILES = sorted(p for p in REPO.glob("*/launch/*.py"))


def _doc(name: str) -> str:
    path = DOCS / name
    assert path.is_file(), f"docs/{name} is missing"
    return path.read_text(encoding="utf-8")


def _named(text: str, name: str) -> bool:
    """Whether `name` appears in `text` as a whole name (not as part of a longer one)."""
    return re.search(rf"(?<![\w/.-]){re.escape(name)}(?![\w/-])", text) is not None


def _names_executable(text: str, name: str) -> bool:
    """Whether `text` names the executable `name` as code: `name` or `ros2 run PACKAGE name`."""
    return f"`{name}`" in text or re.search(rf"ros2 run \w+ {re.escape(name)}\b", text) is not None


def _module_constants(path: Path) -> dict[str, object]:
    """Module-level `NAME = <literal>` assignments of a Python file, without importing it."""
    constants: dict[str, object] = {}
    for node in ast.parse(path.read_text(encoding="utf-8")).body:
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name):
            try:
                constants[node.targets[0].id] = ast.literal_eval(node.value)
            except ValueError:
                continue
    return constants


def _console_scripts(setup: Path) -> list[str]:
    """The executables `setup(entry_points={"console_scripts": [...]})` installs."""
    names = []
    for node in ast.walk(ast.parse(setup.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Dict):
            for key, value in zip(node.keys, node.values, strict=True):
                if isinstance(key, ast.Constant) and key.value == "console_scripts":
                    names += [str(entry).split("=")[0].strip() for entry in ast.literal_eval(value)]
    return names


def test_the_code_offers_what_the_checks_look_for() -> None:
    # a library package may install no executable; together they install the product's commands
    assert {"validate", "plan", "experiment", "vi_node"} <= {n for p in SETUP_FILES for n in _console_scripts(p)}
    assert LAUNCH_FILES
    assert "TOP_KEYS" in _module_constants(STRUCTURE_FILE_PARSER)
    assert any(str(v).startswith("/sim/") for v in _module_constants(SIM_INTERFACE).values())


def test_docs_index_links_every_page() -> None:
    index = _doc("README.md")
    missing = [page for page in ("structure-file.md", "topics.md", "commands.md") if page not in index]
    assert not missing, f"docs/README.md does not link {', '.join(missing)}"


@pytest.mark.parametrize("setup", SETUP_FILES, ids=[p.parent.name for p in SETUP_FILES])
def test_every_executable_is_in_commands(setup: Path) -> None:
    commands = _doc("commands.md")
    missing = [name for name in _console_scripts(setup) if not _names_executable(commands, name)]
    assert not missing, (
        f"docs/commands.md does not mention the executable(s) {', '.join(missing)} "
        f"of {setup.relative_to(REPO)} (console_scripts)"
    )


def test_every_launch_file_is_in_commands() -> None:
    commands = _doc("commands.md")
    missing = [str(p.relative_to(REPO)) for p in LAUNCH_FILES if not _named(commands, p.name)]
    assert not missing, f"docs/commands.md does not mention the launch file(s) {', '.join(missing)}"


def _parser_key_sets() -> dict[str, set[str]]:
    """The key sets the structure-file parser accepts (`*_KEYS` constants of structure_file.py)."""
    return {
        name: set(value)
        for name, value in _module_constants(STRUCTURE_FILE_PARSER).items()
        if name.endswith("_KEYS") and isinstance(value, (set, frozenset, list, tuple))
    }


def test_every_structure_file_key_is_in_structure_file_doc() -> None:
    doc = _doc("structure-file.md")
    key_sets = _parser_key_sets()
    parents = set().union(*key_sets.values())  # a nested key may be written `prism.polygon`
    missing = [
        f"{key} ({constant})"
        for constant, keys in sorted(key_sets.items())
        for key in sorted(keys)
        if f"`{key}`" not in doc and not any(f"`{parent}.{key}`" in doc for parent in parents)
    ]
    assert not missing, (
        f"docs/structure-file.md does not document the structure-file key(s) {', '.join(missing)} "
        f"accepted by {STRUCTURE_FILE_PARSER.relative_to(REPO)}"
    )


@pytest.mark.parametrize("path", sorted((REPO / "config" / "structures").glob("*.yaml")), ids=lambda p: p.name)
def test_example_structures_use_documented_top_level_keys(path: Path) -> None:
    """The parser's TOP_KEYS cover the keys the example files use, and the doc covers both."""
    doc = _doc("structure-file.md")
    used = set(yaml.safe_load(path.read_text(encoding="utf-8")))
    accepted = _parser_key_sets()["TOP_KEYS"]
    assert used <= accepted, f"{path.name} uses keys the parser does not accept: {sorted(used - accepted)}"
    missing = sorted(key for key in used if f"`{key}`" not in doc)
    assert not missing, f"docs/structure-file.md does not document the top-level key(s) {missing} of {path.name}"


def test_every_simulator_topic_is_in_topics() -> None:
    topics = _doc("topics.md")
    declared = {
        name: value
        for name, value in _module_constants(SIM_INTERFACE).items()
        if isinstance(value, str) and value.startswith("/")
    }
    missing = [f"{value} ({name})" for name, value in sorted(declared.items()) if not _named(topics, value)]
    assert not missing, (
        f"docs/topics.md does not mention the simulator-internal name(s) {', '.join(missing)} "
        f"declared in {SIM_INTERFACE.relative_to(REPO)}"
    )
