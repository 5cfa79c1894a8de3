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
from tiling_sim.inspection_scenarios import Scene, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.classify import TileState
from vi_node.inspection_settings import InspectionSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_prior import OverheadPose
from vi_node.scan_result import TileResult

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


def states_from(scene: Scene, tile_id: int, bearings: tuple[float, ...], seeds: tuple[int, int],
                distance: float = 1.0) -> list[TileState]:
    """The states of `tile_id` in simulated scans of `scene` (`results_from`)."""
    return [result.state for result in results_from(scene, tile_id, bearings, seeds, distance)]


def results_from(scene: Scene, tile_id: int, bearings: tuple[float, ...], seeds: tuple[int, int],
                 distance: float = 1.0) -> list[TileResult]:
    """What simulated scans of `scene` from `bearings` (degrees, `distance` m away; `seeds`: of the
    Kinect's noise and of the views' errors) say of `tile_id`, asserting that every scan aligns and
    flags no other tile misplaced."""
    pipeline = InspectionPipeline(scene.structure, None, InspectionSettings())
    simulator = KinectSimulator(seed=seeds[0])
    rng = np.random.default_rng(seeds[1])
    results = []
    for bearing in bearings:
        view = view_from(scene.centre, math.radians(bearing), distance, rng)
        result = pipeline.inspect(simulator.scan(scene.kinect_scene, view.camera),
                                  OverheadPose(*view.overhead))
        assert result.ok, result.reason
        by_id = result.by_id()
        assert [t for t, s in by_id.items() if s.state == TileState.MISPLACED and t != tile_id] == []
        results.append(by_id[tile_id])
    return results
