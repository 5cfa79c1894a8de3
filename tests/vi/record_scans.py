"""Regenerate the recorded scans of tests/data/vi_scans (deterministic; run from the repository root):

    tools/workspace-env python tests/vi/record_scans.py

Scenes of the paper's structure (config/structures/paper_14.yaml) with tiles removed, seen by the
simulated Kinect v1 from several viewpoints with overhead pose errors as in the paper; each bag
folder holds the scans, the overhead poses and truth.json (expected, removed tiles, true poses).
"""

from __future__ import annotations

import math
import shutil
import sys
from pathlib import Path

import numpy as np

from tiling_assembly.structure_file import load_structure
from tiling_sim.inspection_scenarios import Scene, random_clutter, view_from
from tiling_sim.kinect import KINECT_V1_DEPTH, KinectSimulator
from tiling_sim.scan_bag import ScanBagWriter

REPO = Path(__file__).resolve().parents[2]
OUT = REPO / "tests" / "data" / "vi_scans"
STRUCTURE = "config/structures/paper_14.yaml"

# name: (removed tiles, resolution, clutter, [(bearing deg, distance m), ...])
RECORDINGS = {
    "paper_vga": ((10, 13), (640, 480), False, [(-70.0, 1.1), (110.0, 1.25)]),
    "paper_qvga": ((11, 13, 14), (320, 240), True, [(-110.0, 1.0), (-20.0, 1.2), (60.0, 0.9), (160.0, 1.4)]),
}


def record(
    name: str,
    removed: tuple[int, ...],
    size: tuple[int, int],
    clutter: bool,
    views: list[tuple[float, float]],
    seed: int,
) -> Path:
    structure = load_structure(REPO / STRUCTURE)
    rng = np.random.default_rng(seed)
    items = tuple(random_clutter(structure, rng)) if clutter else ()
    scene = Scene(structure, tuple(structure.tile_ids), removed, {}, items)
    simulator = KinectSimulator(KINECT_V1_DEPTH.scaled(*size), seed=seed)
    path = OUT / name
    shutil.rmtree(path, ignore_errors=True)
    with ScanBagWriter(path) as bag:
        bag.set_truth(structure=STRUCTURE, **scene.truth(), clutter=len(items))
        for k, (bearing, distance) in enumerate(views):
            view = view_from(scene.centre, math.radians(bearing), distance, rng)
            stamp = (100 + k) * 10**9
            bag.write_pose(stamp - 2 * 10**6, *view.overhead)  # overhead cameras ~2 ms before the scan
            cloud, labels = simulator.scan_labelled(scene.kinect_scene, view.camera)
            seen = {int(t): int((labels == t).sum()) for t in structure.tile_ids if (labels == t).any()}
            bag.write_scan(stamp, cloud, {"view": view.to_dict(), "visible_pixels": seen})
    return path


def main() -> int:
    for seed, (name, (removed, size, clutter, views)) in enumerate(RECORDINGS.items(), start=1):
        path = record(name, removed, size, clutter, views, seed)
        total = sum(f.stat().st_size for f in path.iterdir())
        print(f"{path.relative_to(REPO)}: {len(views)} scans, {total / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
