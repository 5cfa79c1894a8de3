"""Shared pieces of the visual inspection tests: structures, simulated scans, the ros2 launcher."""

from __future__ import annotations

import functools
import math
import subprocess
from pathlib import Path

import numpy as np
from conftest import ros2_command

from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import load_structure

REPO = Path(__file__).resolve().parents[2]
STRUCTURES = REPO / "config" / "structures"
SCANS = REPO / "tests" / "data" / "vi_scans"


@functools.cache
def structure(name: str = "paper_14") -> Structure:
    return load_structure(STRUCTURES / f"{name}.yaml")


def ros2_run(*args: str, timeout: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [ros2_command(), "run", *args], capture_output=True, text=True, timeout=timeout, cwd=REPO
    )


def overhead_with_error(
    view_base: tuple[float, float, float], shift: float, turn: float, angle: float
) -> tuple[float, float, float]:
    """An overhead pose `shift` m (in direction `angle`) and `turn` rad off the true base pose."""
    x, y, yaw = view_base
    return x + shift * math.cos(angle), y + shift * math.sin(angle), yaw + turn


def rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)
