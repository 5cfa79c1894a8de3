"""The `validate` executable, run as users run it: `ros2 run tiling_assembly validate FILE`."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from conftest import DATA, REPO, STRUCTURES


def _ros2_run(*args: str) -> subprocess.CompletedProcess[str]:
    ros2 = "ros2"
    if not any((Path(p) / "ros2").exists() for p in os.environ.get("PATH", "").split(os.pathsep)):
        ros2 = str(REPO / "tools" / "ros2")
    return subprocess.run([ros2, "run", *args], capture_output=True, text=True, timeout=60)


def test_executables_are_where_ros2_run_looks() -> None:
    prefix = REPO / "install" / "tiling_assembly" / "lib" / "tiling_assembly"
    assert os.access(prefix / "validate", os.X_OK)


def test_valid_file_prints_the_summary() -> None:
    result = _ros2_run("tiling_assembly", "validate", str(STRUCTURES / "paper_14.yaml"))
    assert result.returncode == 0, result.stderr
    assert "14 tiles of 5 types in 4 layers" in result.stdout
    assert "layer 3: 13 triangle, 14 triangle" in result.stdout
    assert "11 long_rectangle" in result.stdout and "<- 4, 9" in result.stdout


def test_invalid_file_gives_one_line_and_exit_code_2() -> None:
    bad = DATA / "structures" / "invalid" / "overlapping_tiles.yaml"
    result = _ros2_run("tiling_assembly", "validate", str(bad))
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"error: {bad}: overlap [tiles 1, 2]")
    assert "Traceback" not in result.stderr


def test_missing_file_is_not_a_traceback() -> None:
    result = _ros2_run("tiling_assembly", "validate", "/nonexistent/structure.yaml")
    assert result.returncode == 2
    assert "Traceback" not in result.stderr
    assert "cannot read the file" in result.stderr


def test_unknown_executable_is_reported() -> None:
    result = _ros2_run("tiling_assembly", "no_such_tool")
    assert result.returncode != 0
    assert "no_such_tool" in result.stderr


def test_python_module_entry_point_matches() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "tiling_assembly.validate", "--quiet", str(STRUCTURES / "gate_9.yaml")],
        capture_output=True, text=True, timeout=60,
    )
    assert result.returncode == 0 and result.stdout == ""
