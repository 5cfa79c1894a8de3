"""The code's layout rules (ROS-free checks on the sources): no import circle between the packages'
modules, QoS profiles built in one module, a ROS-free core, no function too long to read at once."""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import networkx as nx
from conftest import REPO

PACKAGES = ("assembly_node", "auction_node", "planner_node", "vi_node", "hardware_drivers", "tiling_sim",
            "tiling_assembly", "tiling_ros")
LONGEST_FUNCTION = 80  # lines


def modules() -> Iterator[tuple[str, ast.Module, Path]]:
    for package in PACKAGES:
        for path in sorted((REPO / package / package).glob("*.py")):
            yield f"{package}.{path.stem}", ast.parse(path.read_text(), str(path)), path


def imported(tree: ast.Module) -> Iterator[str]:
    """The package modules `tree` imports, also inside functions."""
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module and node.module.split(".")[0] in PACKAGES:
            if "." in node.module:
                yield node.module
            else:  # from package import module
                yield from (f"{node.module}.{alias.name}" for alias in node.names)
        elif isinstance(node, ast.Import):
            yield from (a.name for a in node.names if a.name.split(".")[0] in PACKAGES)


def test_no_module_imports_itself_through_others() -> None:
    graph = nx.DiGraph((name, target) for name, tree, _ in modules() for target in imported(tree))
    assert list(nx.simple_cycles(graph)) == []


def test_qos_profiles_are_built_in_one_module() -> None:
    builders = [str(path.relative_to(REPO)) for _, tree, path in modules()
                if any(isinstance(n, ast.Call) and isinstance(n.func, ast.Name) and n.func.id == "QoSProfile"
                       for n in ast.walk(tree))]
    assert builders == ["tiling_ros/tiling_ros/qos.py"]


def test_the_core_imports_no_rclpy() -> None:
    core = [name for name, tree, _ in modules() if name.startswith("tiling_assembly.")
            for node in ast.walk(tree) if isinstance(node, ast.Import | ast.ImportFrom)
            and any(n.startswith("rclpy") for n in ([node.module or ""] if isinstance(node, ast.ImportFrom)
                                                    else [a.name for a in node.names]))]
    assert core == []


def test_no_function_is_too_long_to_read_at_once() -> None:
    long = [f"{path.relative_to(REPO)}:{node.lineno} {node.name} ({node.end_lineno - node.lineno + 1} lines)"
            for _, tree, path in modules() for node in ast.walk(tree)
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef)
            and node.end_lineno - node.lineno + 1 > LONGEST_FUNCTION]
    assert long == []
