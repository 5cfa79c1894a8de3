"""`ros2 run tiling_sim classify_benchmark`: what `ros2 run vi_node classify` costs a user per scan,
as a whole process (start-up, bag decoding, cloud conversion, pipeline, JSON out).

    ros2 run tiling_sim classify_benchmark [--few 2] [--many 16] [--repeat 3] [--jobs 2,1] [--seed S]

Two rosbag2 folders of simulated 640x480 Kinect scans of the paper's structure are written, one
with `few` and one with `many` scans (the same first scans). The installed `classify` runs on both,
alternating, `repeat` times per job count; the difference of the median wall times divided by
`many - few` is the cost per extra scan, start-up and loading cancelled out. Each run's JSON lines
are checked: one per scan.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from tiling_assembly.structure_file import load_structure
from tiling_sim.inspection_scenarios import structure_path
from tiling_sim.scan_bag import ScanBagWriter
from tiling_sim.vi_benchmark import scans_for


def write_bag(path: Path, scans: list, count: int) -> None:  # type: ignore[type-arg]
    """The first `count` scans, each with its overhead pose 5 ms before it."""
    with ScanBagWriter(path) as bag:
        for k, (cloud, overhead, _) in enumerate(scans[:count]):
            stamp = (k + 1) * 500_000_000
            bag.write_pose(stamp - 5_000_000, overhead.x, overhead.y, overhead.yaw)
            bag.write_scan(stamp, cloud)


def classify_executable() -> str:
    from ament_index_python.packages import get_package_prefix

    return str(Path(get_package_prefix("vi_node")) / "lib" / "vi_node" / "classify")


def time_classify(executable: str, structure: str, bag: Path, jobs: int, scans: int) -> float:
    """Wall seconds of one whole `classify` process on `bag`."""
    tick = time.perf_counter()
    done = subprocess.run([executable, "--structure", structure, "--bag", str(bag), "--jobs", str(jobs)],
                          capture_output=True, text=True)  # fmt: skip
    seconds = time.perf_counter() - tick
    lines = done.stdout.splitlines()
    if done.returncode != 0 or len(lines) != scans:
        raise RuntimeError(f"classify failed on {bag} (exit {done.returncode}, {len(lines)} lines): "
                           f"{done.stderr.strip().splitlines()[-1:]}")
    return seconds


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="ros2 run tiling_sim classify_benchmark",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--few", type=int, default=2, help="scans in the small bag")
    parser.add_argument("--many", type=int, default=16, help="scans in the large bag")
    parser.add_argument("--repeat", type=int, default=3, help="runs per bag and job count")
    parser.add_argument("--jobs", default="2,1", help="comma-separated --jobs values of classify to time")
    parser.add_argument("--structure", default="paper_14")
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args(argv)
    try:
        jobs = [int(j) for j in args.jobs.split(",") if j]
    except ValueError:
        jobs = []
    if not 1 <= args.few < args.many or args.repeat < 1 or not jobs or min(jobs) < 1:
        print("error: need 1 <= --few < --many, --repeat >= 1 and --jobs of positive integers", file=sys.stderr)
        return 2
    structure_file = str(structure_path(args.structure))
    print(f"simulating {args.many} Kinect scans ...", file=sys.stderr, flush=True)
    scans = scans_for(load_structure(structure_file), args.many, args.seed)
    executable = classify_executable()
    with tempfile.TemporaryDirectory(prefix="classify_benchmark_") as folder:
        bags = {count: Path(folder) / f"scans_{count}" for count in (args.few, args.many)}
        for count, path in bags.items():
            write_bag(path, scans, count)
        times: dict[tuple[int, int], list[float]] = {(j, c): [] for j in jobs for c in bags}
        for rep in range(args.repeat):
            print(f"run {rep + 1}/{args.repeat} ...", file=sys.stderr, flush=True)
            for j in jobs:  # interleaved, so that machine load hits every case alike
                for count, path in bags.items():
                    times[(j, count)].append(time_classify(executable, structure_file, path, j, count))
    print(f"`classify` whole process, 640x480 scans of {args.structure}, median of {args.repeat} runs:")
    for j in jobs:
        few, many = (statistics.median(times[(j, c)]) for c in (args.few, args.many))
        extra = (many - few) / (args.many - args.few)
        print(f"  --jobs {j}: {args.few} scans {few:.2f} s, {args.many} scans {many:.2f} s, "
              f"per extra scan {extra * 1e3:.1f} ms, start-up and first scans {few - args.few * extra:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
