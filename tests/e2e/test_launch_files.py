"""The launch files that run the team on real robots (assembly robots, team nodes, inspection).

There is no `launch` package on this machine, so they are checked statically: they compile, use
only the launch / launch_ros API, and every executable, launch file and parameter file they name
is one the workspace installs.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from conftest import REPO

LAUNCH_FILES = [
    REPO / "assembly_node/launch/assembly_robot.launch.py",
    REPO / "auction_node/launch/team.launch.py",
    REPO / "vi_node/launch/inspection.launch.py",
]


def _calls(tree: ast.AST, name: str) -> list[ast.Call]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.Call) and getattr(n.func, "id", "") == name]


def _share_paths(tree: ast.AST) -> list[tuple[str, ...]]:
    """The constant parts of every PathJoinSubstitution([FindPackageShare(pkg), part, ...])."""
    found = []
    for call in _calls(tree, "PathJoinSubstitution"):
        parts = call.args[0].elts  # type: ignore[attr-defined]
        first = parts[0]
        if isinstance(first, ast.Call) and getattr(first.func, "id", "") == "FindPackageShare":
            rest = [p.value for p in parts[1:] if isinstance(p, ast.Constant)]
            found.append((first.args[0].value, *rest))  # type: ignore[attr-defined]
    return found


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=lambda p: p.name)
def test_launch_file_names_only_what_the_workspace_installs(path: Path) -> None:
    tree = ast.parse(path.read_text(), str(path))
    compile(tree, str(path), "exec")
    modules = {n.module.split(".")[0] for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}
    assert modules <= {"launch", "launch_ros"}
    assert "generate_launch_description" in [n.name for n in tree.body if isinstance(n, ast.FunctionDef)]
    nodes = _calls(tree, "Node")
    assert nodes
    for node in nodes:
        keywords = {k.arg: k.value for k in node.keywords}
        package, executable = keywords["package"].value, keywords["executable"].value  # type: ignore[attr-defined]
        assert (REPO / "install" / package / "lib" / package / executable).exists(), f"{package} {executable}"
    shares = _share_paths(tree)
    assert shares
    for package, *parts in shares:
        if parts and parts[-1].endswith((".yaml", ".py")):
            installed = REPO / "install" / package / "share" / package / Path(*parts)
            assert installed.exists(), f"{installed} is not installed"


def test_every_team_node_of_the_simulation_has_a_real_robot_launch() -> None:
    text = "\n".join(p.read_text() for p in LAUNCH_FILES)
    for executable in ("assembly_node", "planner_node", "auction_node", "vi_node", "vi_explorer"):
        assert f'executable="{executable}"' in text
    assert '"m3_robot.launch.py"' in text and '"vi_robot.launch.py"' in text
