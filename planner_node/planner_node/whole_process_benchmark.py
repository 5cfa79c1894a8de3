"""`benchmark --whole-process`: the `plan` command timed as a user runs it, one process per plan.

Issue 15's targets: loading, validating and deriving supports for 10,000 tiles in at most 1 s, and
the whole `plan` process for 10,000 tiles and 16 robots in at most 2 s (best of 2) with a makespan
within 1.01 x the lower bound. Every generated structure is written to a YAML file as a user would
have it; loading it is timed in this process (best of the runs); then the `plan` executable runs
on it `--repeat` times, the structures taking turns so that a busy spell of the machine spreads
over all of them. Each run's wall-clock time is taken around the process, its CPU time from the
operating system (less disturbed by other work on the machine), and its stages from the command's
own `--timings` line: startup (the interpreter and the imports), load, plan (and the planner's
stages), output.
"""

from __future__ import annotations

import json
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from planner_node.structure_generators import GENERATORS
from tiling_assembly.structure_file import load_structure

TARGET_LOAD_SECONDS = 1.0
TARGET_PROCESS_SECONDS = 2.0
TARGET_RATIO = 1.01


@dataclass
class Case:
    """One structure file and what its `plan` runs measured."""

    kind: str
    size: int  # the size asked for; `tiles` is what the generator made of it
    path: Path
    tiles: int
    robots: int
    load_seconds: list[float] = field(default_factory=list)
    wall: list[float] = field(default_factory=list)
    cpu: list[float] = field(default_factory=list)
    stages: list[dict[str, float]] = field(default_factory=list)
    ratio: float = 0.0

    def best_of_two(self) -> float:
        return min(self.wall[:2])

    def stage_medians(self) -> dict[str, float]:
        names = dict.fromkeys(name for run in self.stages for name in run)
        return {name: statistics.median(run[name] for run in self.stages if name in run) for name in names}


def plan_executable() -> list[str]:
    """The installed `plan` executable (the script `ros2 run` starts), else the module."""
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix
    except ImportError:
        return [sys.executable, "-m", "planner_node.plan_command"]
    try:
        script = Path(get_package_prefix("planner_node")) / "lib" / "planner_node" / "plan"
    except PackageNotFoundError:
        script = Path("/nonexistent")
    return [str(script)] if script.exists() else [sys.executable, "-m", "planner_node.plan_command"]


def write_structure(kind: str, size: int, folder: Path) -> Path:
    """A generated structure as a YAML file in the generators' block style."""
    document = json.loads(json.dumps(GENERATORS[kind](size), default=float))  # numpy numbers as floats
    path = folder / f"{kind}_{size}.yaml"
    path.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    return path


def time_plan_process(command: list[str], case: Case) -> None:
    """Run `plan` once on the case; record its wall-clock and CPU seconds, stages and ratio."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    tic = time.perf_counter()
    run = subprocess.run(
        [*command, "--structure", str(case.path), "--robots", str(case.robots), "--timings"],
        capture_output=True, text=True, check=False,
    )
    case.wall.append(time.perf_counter() - tic)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    case.cpu.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    if run.returncode != 0:
        raise RuntimeError(f"plan failed on {case.path} (exit {run.returncode}): {run.stderr.strip()}")
    output = json.loads(run.stdout)
    case.ratio = output["makespan"] / output["lower_bound"] if output["lower_bound"] else 1.0
    for line in run.stderr.splitlines():
        if line.startswith("timings: "):
            case.stages.append(json.loads(line.removeprefix("timings: ")))


def format_report(cases: list[Case]) -> str:
    stage_names = list(dict.fromkeys(name for case in cases for name in case.stage_medians()))
    head = (f"{'structure':<9} {'tiles':>6} {'robots':>6} | {'load':>5} | {'best2':>6} {'median':>6} {'cpu':>6} |"
            f" {'ratio':>6} | stage medians (s): " + " ".join(stage_names))
    lines = [head, "-" * len(head)]
    for case in cases:
        stages = case.stage_medians()
        lines.append(
            f"{case.kind:<9} {case.tiles:>6} {case.robots:>6} | {min(case.load_seconds):5.2f} |"
            f" {case.best_of_two():6.2f} {statistics.median(case.wall):6.2f} {statistics.median(case.cpu):6.2f} |"
            f" {case.ratio:6.4f} | " + " ".join(f"{stages.get(name, float('nan')):.3f}" for name in stage_names)
        )
    lines.append(
        "load: loading, validating and deriving supports in this process (best of the runs); best2: wall-clock "
        "seconds of the whole `plan` process, best of the first 2 runs; median, cpu: median over all runs"
    )
    return "\n".join(lines)


def verdicts(cases: list[Case]) -> str:
    lines = []
    for case in cases:
        if case.size < 10_000 or case.robots != 16:
            continue
        load_ok = min(case.load_seconds) <= TARGET_LOAD_SECONDS
        process_ok = case.best_of_two() <= TARGET_PROCESS_SECONDS
        ratio_ok = case.ratio <= TARGET_RATIO
        lines.append(
            f"{case.kind} {case.tiles} tiles, 16 robots: load {'meets' if load_ok else 'misses'} "
            f"<= {TARGET_LOAD_SECONDS:.0f} s, whole process {'meets' if process_ok else 'misses'} "
            f"<= {TARGET_PROCESS_SECONDS:.0f} s, makespan {'meets' if ratio_ok else 'misses'} <= {TARGET_RATIO} x LB"
        )
    return "\n".join(lines)


def run_whole_process(kinds: list[str], sizes: list[int], robots: list[int], repeat: int) -> int:
    """Time the `plan` process on every kind, size and team size (see the module docstring)."""
    command = plan_executable()
    print(f"timing {' '.join(command)} ({repeat} runs per case)", file=sys.stderr, flush=True)
    with tempfile.TemporaryDirectory(prefix="plan-benchmark-") as folder:
        cases = []
        for kind in kinds:
            for size in sizes:
                path = write_structure(kind, size, Path(folder))
                tiles = len(load_structure(path))
                cases += [Case(kind, size, path, tiles, n) for n in robots]
        for round_number in range(repeat):
            for case in cases:
                tic = time.perf_counter()
                load_structure(case.path)
                case.load_seconds.append(time.perf_counter() - tic)
                time_plan_process(command, case)
            print(f"[{round_number + 1}/{repeat}] " + ", ".join(f"{c.kind} {c.wall[-1]:.2f} s" for c in cases),
                  file=sys.stderr, flush=True)
    print(format_report(cases))
    summary = verdicts(cases)
    if summary:
        print(summary)
    return 0
