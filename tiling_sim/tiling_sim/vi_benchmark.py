"""`ros2 run tiling_sim vi_benchmark`: time the inspection per 640x480 scan, stage by stage, next to
a plain Open3D pipeline a user would write, in the same run on the same scans.

    ros2 run tiling_sim vi_benchmark [--scans N] [--repeat R] [--modes default,paper] [--seed S]

The scans are simulated Kinect v1 frames of the paper's structure (a few tiles removed) from
viewpoints around it, with the paper's overhead errors. Every pipeline runs on every scan `repeat`
times (after one warm-up pass); the medians per stage and of the total are printed, and the
ratio plain / ours. Models built once per expected structure (patches, ray casting scenes, model
samples) are built before timing, for every pipeline alike.

The plain pipeline: `segment_plane` (RANSAC) on the whole cloud for the floor, crop to the
structure's box, `registration_icp` point-to-plane (10 iterations) against points sampled from the
structure's mesh, from the overhead pose prior; a `RaycastingScene` casting every pixel at the
aligned pose; physical support by nearest-neighbour search of the aligned points among the virtual
hits; the paper's rules.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from collections import defaultdict

import numpy as np

from tiling_assembly.geometry import PlacedTile
from tiling_assembly.open3d_loader import import_open3d
from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import load_structure
from tiling_sim.inspection_scenarios import Scene, remove_tiles, structure_path, view_from
from tiling_sim.kinect import KinectSimulator
from vi_node.camera_model import PinholeCamera
from vi_node.classify import classify_paper
from vi_node.inspection_settings import MODES, InspectionSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_prior import CameraMount, OverheadPose, camera_prior


class PlainOpen3DPipeline:
    """What a user would write with Open3D's stock tools (no attempt to be clever)."""

    def __init__(self, structure: Structure, settings: InspectionSettings) -> None:
        o3d = import_open3d()
        self.o3d = o3d
        self.settings = settings
        fx, fy, cx, cy = settings.intrinsics
        self.camera = PinholeCamera(fx, fy, cx, cy, *settings.intrinsics_size)
        self.mount = CameraMount(tuple(settings.camera_xyz), tuple(settings.camera_rpy))  # type: ignore[arg-type]
        tiles: list[PlacedTile] = list(structure.tiles.values())
        self.tile_ids = np.array([t.tile_id for t in tiles])
        vertices, triangles, owner = [], [], []
        offset = 0
        for k, tile in enumerate(tiles):
            tris, _ = tile.triangles
            vertices.append(tile.vertices)
            triangles.append(tris + offset)
            owner.append(np.full(len(tris), k))
            offset += len(tile.vertices)
        self.triangle_tile = np.concatenate(owner)
        mesh = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector(np.vstack(vertices)), o3d.utility.Vector3iVector(np.vstack(triangles))
        )
        mesh.compute_triangle_normals()
        self.model = mesh.sample_points_uniformly(number_of_points=20000, use_triangle_normal=True)
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
        h = 30.0
        floor = o3d.geometry.TriangleMesh(
            o3d.utility.Vector3dVector([[-h, -h, 0], [h, -h, 0], [h, h, 0], [-h, h, 0]]),
            o3d.utility.Vector3iVector([[0, 1, 2], [0, 2, 3]]),
        )
        self.scene.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(floor))
        self.low, self.high = structure.bounds

    def inspect(self, cloud: np.ndarray, overhead: OverheadPose) -> dict[str, float]:
        o3d = self.o3d
        times: dict[str, float] = {}
        tick = time.perf_counter()

        def lap(stage: str) -> None:
            nonlocal tick
            now = time.perf_counter()
            times[stage] = now - tick
            tick = now

        points = cloud.reshape(-1, 3)
        points = points[np.isfinite(points[:, 2])].astype(np.float64)
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
        lap("convert")
        _, floor = pcd.segment_plane(distance_threshold=0.01, ransac_n=3, num_iterations=1000)
        rest = pcd.select_by_index(floor, invert=True)
        lap("floor")
        prior = camera_prior(overhead, self.mount)
        rest.transform(prior)
        box = o3d.geometry.AxisAlignedBoundingBox(self.low - 0.03, self.high + 0.03)
        candidates = rest.crop(box)
        lap("candidates")
        icp = o3d.pipelines.registration.registration_icp(
            candidates,
            self.model,
            0.03,
            np.eye(4),
            o3d.pipelines.registration.TransformationEstimationPointToPlane(),
            o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=10),
        )
        candidates.transform(icp.transformation)
        pose = icp.transformation @ prior
        lap("icp")
        rays = self.camera.rays.reshape(-1, 3) @ pose[:3, :3].T
        origins = np.broadcast_to(pose[:3, 3], rays.shape)
        hits = self.scene.cast_rays(o3d.core.Tensor(np.hstack([origins, rays]).astype(np.float32)))
        t = hits["t_hit"].numpy()
        geometry = hits["geometry_ids"].numpy()
        on_structure = geometry == 0
        virtual_points = origins[on_structure] + rays[on_structure] * t[on_structure, None]
        virtual_tile = self.triangle_tile[hits["primitive_ids"].numpy()[on_structure]]
        lap("raycast")
        virtual = np.bincount(virtual_tile, minlength=len(self.tile_ids))
        physical = np.zeros(len(self.tile_ids), dtype=np.int64)
        measured = np.asarray(candidates.points)
        if len(measured) and len(virtual_points):
            search = o3d.core.nns.NearestNeighborSearch(o3d.core.Tensor(virtual_points.astype(np.float32)))
            search.knn_index()
            index, distance2 = search.knn_search(o3d.core.Tensor(measured.astype(np.float32)), 1)
            near = distance2.numpy()[:, 0] <= 0.015**2
            physical = np.bincount(virtual_tile[index.numpy()[near, 0]], minlength=len(self.tile_ids))
        classify_paper(physical, virtual)
        lap("classify")
        return times


def scans_for(
    structure: Structure, count: int, seed: int
) -> list[tuple[np.ndarray, OverheadPose, tuple[int, ...]]]:
    rng = np.random.default_rng(seed)
    simulator = KinectSimulator(seed=seed)
    scans = []
    for k in range(count):
        removed = remove_tiles(structure, structure.tile_ids, rng, 2)
        scene = Scene(structure, tuple(structure.tile_ids), removed)
        view = view_from(
            scene.centre, 2 * math.pi * k / count + rng.uniform(-0.2, 0.2), rng.uniform(0.9, 1.4), rng
        )
        scans.append(
            (simulator.scan(scene.kinect_scene, view.camera), OverheadPose(*view.overhead), scene.expected)
        )
    return scans


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="ros2 run tiling_sim vi_benchmark", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--scans", type=int, default=12, help="simulated 640x480 scans")
    parser.add_argument("--repeat", type=int, default=3, help="timed passes over the scans")
    parser.add_argument("--modes", default=",".join(MODES), help="inspection modes to time")
    parser.add_argument("--structure", default="paper_14")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args(argv)
    modes = [m for m in args.modes.split(",") if m]
    if any(m not in MODES for m in modes) or args.scans < 1 or args.repeat < 1:
        print(
            f"error: modes must be among {', '.join(MODES)}; --scans and --repeat at least 1", file=sys.stderr
        )
        return 2
    structure = load_structure(structure_path(args.structure))
    print(f"simulating {args.scans} Kinect scans of {structure.name} ...", file=sys.stderr, flush=True)
    scans = scans_for(structure, args.scans, args.seed)
    ours = {
        m: InspectionPipeline(structure, None, InspectionSettings().with_values({"mode": m})) for m in modes
    }
    plain = PlainOpen3DPipeline(structure, InspectionSettings())
    timings: dict[str, dict[str, list[float]]] = {
        name: defaultdict(list) for name in [*modes, "plain Open3D"]
    }
    for rep in range(args.repeat + 1):  # pass 0 warms up (imports, first allocations)
        print(f"pass {rep}/{args.repeat}{' (warm-up)' if rep == 0 else ''} ...", file=sys.stderr, flush=True)
        for cloud, overhead, _ in scans:  # interleaved, so that machine load hits every pipeline alike
            for mode, pipeline in ours.items():
                tick = time.perf_counter()
                result = pipeline.inspect(cloud, overhead)
                total = time.perf_counter() - tick
                if rep:
                    for stage, seconds in result.timings.items():
                        timings[mode][stage].append(seconds)
                    timings[mode]["total"].append(total)
            tick = time.perf_counter()
            stages = plain.inspect(cloud, overhead)
            total = time.perf_counter() - tick
            if rep:
                for stage, seconds in stages.items():
                    timings["plain Open3D"][stage].append(seconds)
                timings["plain Open3D"]["total"].append(total)
    print(
        f"Median time per 640x480 scan over {args.scans} scans x {args.repeat} passes "
        f"({structure.name}, {len(structure)} tiles expected), milliseconds:"
    )
    for name, stages in timings.items():
        parts = "  ".join(
            f"{stage} {statistics.median(v) * 1e3:.1f}" for stage, v in stages.items() if stage != "total"
        )
        print(f"  {name:14s} total {statistics.median(stages['total']) * 1e3:7.1f}   ({parts})")
    reference = statistics.median(timings["plain Open3D"]["total"])
    for mode in modes:
        ratio = reference / statistics.median(timings[mode]["total"])
        print(f"  plain Open3D / {mode}: {ratio:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
