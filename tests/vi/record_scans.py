"""Regenerate the recorded scans of tests/data/vi_scans (deterministic; run from the repository root):

    tools/workspace-env python tests/vi/record_scans.py

Scenes of the paper's structure (config/structures/paper_14.yaml) with tiles removed (and one
misplaced), seen by the
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
from tiling_sim.inspection_scenarios import Scene, misplace_tile, random_clutter, view_from
from tiling_sim.kinect import KINECT_V1_DEPTH, KinectSimulator
from tiling_sim.scan_bag import ScanBagWriter

REPO = Path(__file__).resolve().parents[2]
OUT = REPO / "tests" / "data" / "vi_scans"
STRUCTURE = "config/structures/paper_14.yaml"

# name: (removed tiles, misplaced (tile, "shift" | "turn") or None, resolution, clutter,
#        [(bearing deg, distance m), ...])
RECORDINGS: dict[
    str, tuple[tuple[int, ...], tuple[int, str] | None, tuple[int, int], bool, list[tuple[float, float]]]
] = {
    "paper_vga": ((10, 13), None, (640, 480), False, [(-70.0, 1.1), (110.0, 1.25)]),
    "paper_qvga": (
        (11, 13, 14),
        None,
        (320, 240),
        True,
        [(-110.0, 1.0), (-20.0, 1.2), (60.0, 0.9), (160.0, 1.4)],
    ),
    "paper_misplaced_qvga": ((13,), (11, "turn"), (320, 240), False, [(-80.0, 0.95), (100.0, 1.0)]),
}


def record(
    name: str,
    removed: tuple[int, ...],
    misplaced: tuple[int, str] | None,
    size: tuple[int, int],
    clutter: bool,
    views: list[tuple[float, float]],
    seed: int,
) -> Path:
    structure = load_structure(REPO / STRUCTURE)
    rng = np.random.default_rng(seed)
    items = tuple(random_clutter(structure, rng)) if clutter else ()
    moved = {}
    if misplaced is not None:
        tile, kind = misplaced
        others = [t for t in structure.tile_ids if t not in removed and t != tile]
        placed = misplace_tile(structure, tile, others, rng, kind=kind)
        assert placed is not None, f"no room to misplace tile {tile}"
        moved[tile] = placed
    scene = Scene(structure, tuple(structure.tile_ids), removed, moved, items)
    simulator = KinectSimulator(KINECT_V1_DEPTH.scaled(*size), seed=seed)
    path = OUT / name
    shutil.rmtree(path, ignore_errors=True)
    with ScanBagWriter(path) as bag:
        where = {
            str(t): {"position": p.position.round(5).tolist(), "yaw": round(p.yaw, 5)}
            for t, p in moved.items()
        }
        bag.set_truth(structure=STRUCTURE, **scene.truth(), clutter=len(items), misplaced_pose=where)
        for k, (bearing, distance) in enumerate(views):
            view = view_from(scene.centre, math.radians(bearing), distance, rng)
            stamp = (100 + k) * 10**9
            bag.write_pose(stamp - 2 * 10**6, *view.overhead)  # overhead cameras ~2 ms before the scan
            cloud, labels = simulator.scan_labelled(scene.kinect_scene, view.camera)
            seen = {int(t): int((labels == t).sum()) for t in structure.tile_ids if (labels == t).any()}
            bag.write_scan(stamp, cloud, {"view": view.to_dict(), "visible_pixels": seen})
    return path


def main() -> int:
    for seed, (name, (removed, misplaced, size, clutter, views)) in enumerate(RECORDINGS.items(), start=1):
        path = record(name, removed, misplaced, size, clutter, views, seed)
        total = sum(f.stat().st_size for f in path.iterdir())
        print(f"{path.relative_to(REPO)}: {len(views)} scans, {total / 1e6:.2f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
