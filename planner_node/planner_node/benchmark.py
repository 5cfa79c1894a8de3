"""`benchmark`: plan generated structures with every method and compare them side by side.

    ros2 run planner_node benchmark [--sizes 100 1000 10000] [--robots 2 4 8 16]
                                    [--kinds wall pyramid bridge cluster] [--repeat K]
                                    [--params FILE] [--chart FILE.png] [--whole-process]

For every structure (walls, pyramids, bridges, random clusters of about each size, see
`structure_generators`) and team size it plans with the paper's method, the default method and a
round-robin-by-layer baseline, and prints planning time (median wall clock of K runs; the summary
also gives CPU time, which a busy machine disturbs less), makespan / lower bound,
workload imbalance (max/mean) and total waiting time. Progress goes to stderr, the table to stdout;
`--chart` also draws makespan / lower bound as a PNG. Generating and validating the structures
(the core's loader) is timed apart: it is not planning time.

`--whole-process` times the `plan` command instead, as a process on structure files, with its
stages (`whole_process_benchmark`; by default 10,000 tiles, 16 robots, 3 runs per structure).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import dataclass

from planner_node.parameters import ParameterError, PlannerParameters, read_parameter_file
from planner_node.planner import Method, Plan, default_robot_names, plan_assembly
from planner_node.structure_generators import GENERATORS
from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import parse_structure

METHODS = (Method.PAPER, Method.DEFAULT, Method.ROUND_ROBIN)
SHORT = {Method.PAPER: "paper", Method.DEFAULT: "default", Method.ROUND_ROBIN: "rr"}
TARGET_RATIO = 1.05
TARGET_SECONDS = 2.0


@dataclass(frozen=True)
class Row:
    kind: str
    size: int  # the size asked for; `tiles` is what the generator made of it
    tiles: int
    robots: int
    load_seconds: float
    seconds: dict[Method, float]  # wall clock
    cpu_seconds: dict[Method, float]  # this process's CPU time (less sensitive to a busy machine)
    plans: dict[Method, Plan]


def run_case(structure: Structure, robots: int, parameters: PlannerParameters, repeat: int) -> tuple[
    dict[Method, float], dict[Method, float], dict[Method, Plan]
]:
    """Plan with every method `repeat` times: median wall-clock and CPU seconds, and the plans."""
    seconds, cpu, plans = {}, {}, {}
    names = default_robot_names(robots)
    for method in METHODS:
        wall_times, cpu_times = [], []
        for _ in range(repeat):
            tic, tic_cpu = time.perf_counter(), time.process_time()
            options = {**parameters.planning_options(), "method": method}
            plans[method] = plan_assembly(structure, names, parameters.time_model(), **options)
            wall_times.append(time.perf_counter() - tic)
            cpu_times.append(time.process_time() - tic_cpu)
        seconds[method] = statistics.median(wall_times)
        cpu[method] = statistics.median(cpu_times)
    return seconds, cpu, plans


def _cells(values: list[str], width: int) -> str:
    return " ".join(f"{v:>{width}}" for v in values)


def format_table(rows: list[Row]) -> str:
    groups = [
        ("plan time (s)", 7), ("makespan / lower bound", 7), ("imbalance max/mean", 7), ("total wait (s)", 9)
    ]
    head1 = f"{'structure':<9} {'tiles':>6} {'robots':>6} |" + "|".join(
        f" {title:^{3 * w + 2}} " for title, w in groups
    )
    head2 = f"{'':<9} {'':>6} {'':>6} |" + "|".join(
        " " + _cells([SHORT[m] for m in METHODS], w) + " " for _, w in groups
    )
    lines = [head1, head2, "-" * len(head2)]
    for row in rows:
        p = row.plans
        lines.append(
            f"{row.kind:<9} {row.tiles:>6} {row.robots:>6} |"
            + " " + _cells([f"{row.seconds[m]:.3f}" for m in METHODS], 7) + " |"
            + " " + _cells([f"{p[m].ratio:.3f}" for m in METHODS], 7) + " |"
            + " " + _cells([f"{p[m].imbalance:.3f}" for m in METHODS], 7) + " |"
            + " " + _cells([f"{p[m].total_wait:.0f}" for m in METHODS], 9) + " "
        )
    return "\n".join(lines)


def summary(rows: list[Row]) -> str:
    lines = []
    for method in METHODS:
        ratios = [r.plans[method].ratio for r in rows]
        worst = max(rows, key=lambda r: r.plans[method].ratio)
        met = sum(x <= TARGET_RATIO for x in ratios)
        lines.append(
            f"{method.value:>12}: makespan/LB median {statistics.median(ratios):.3f}, "
            f"worst {max(ratios):.3f} ({worst.kind} {worst.tiles} tiles, {worst.robots} robots); "
            f"<= {TARGET_RATIO} in {met}/{len(rows)}"
        )
    misses = [r for r in rows if r.plans[Method.DEFAULT].ratio > TARGET_RATIO]
    if misses:
        lines.append(
            f"default plans above {TARGET_RATIO} x lower bound, against the strongest bound "
            "(also counting that some robot places ceil(n/N) tiles):"
        )
        for r in misses:
            p = r.plans[Method.DEFAULT]
            lines.append(
                f"  {r.kind} {r.tiles} tiles, {r.robots} robots: {p.ratio:.3f} x LB = "
                f"{p.makespan / p.bound.strongest:.3f} x strongest bound "
                f"({r.tiles / r.robots:.1f} tiles per robot)"
            )
    largest = max(r.size for r in rows)
    big = [r for r in rows if r.size == largest and r.size >= 10_000 and r.robots == 16]
    for r in big:
        verdict = "meets" if r.seconds[Method.DEFAULT] <= TARGET_SECONDS else "misses"
        lines.append(
            f"{r.kind} {r.tiles} tiles, 16 robots: default plans in {r.seconds[Method.DEFAULT]:.2f} s "
            f"({verdict} the {TARGET_SECONDS:.0f} s target; {r.cpu_seconds[Method.DEFAULT]:.2f} s of CPU), "
            f"paper {r.seconds[Method.PAPER]:.2f} s ({r.cpu_seconds[Method.PAPER]:.2f} s of CPU)"
        )
    return "\n".join(lines)


def draw_chart(rows: list[Row], path: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    kinds = list(dict.fromkeys(r.kind for r in rows))
    figure, axes = plt.subplots(len(kinds), 1, figsize=(12, 3.2 * len(kinds)), squeeze=False)
    width = 0.27
    for ax, kind in zip(axes[:, 0], kinds, strict=True):
        mine = [r for r in rows if r.kind == kind]
        for k, method in enumerate(METHODS):
            ax.bar(
                [i + (k - 1) * width for i in range(len(mine))],
                [r.plans[method].ratio for r in mine],
                width,
                label=method.value,
            )
        ax.axhline(TARGET_RATIO, color="black", linestyle="--", linewidth=1, label=f"{TARGET_RATIO} x bound")
        ax.set_xticks(range(len(mine)), [f"{r.tiles}\n{r.robots} rob." for r in mine], fontsize=8)
        ax.set_ylabel("makespan / lower bound")
        ax.set_title(kind)
        ax.set_ylim(0.95, max(1.2, max(r.plans[m].ratio for r in mine for m in METHODS) + 0.05))
        ax.legend(fontsize=8, ncol=4, loc="upper left")
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmark", description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", help="default: 100 1000 10000 (--whole-process: 10000)")
    parser.add_argument("--robots", type=int, nargs="+", help="default: 2 4 8 16 (--whole-process: 16)")
    parser.add_argument("--kinds", nargs="+", choices=sorted(GENERATORS), default=list(GENERATORS))
    parser.add_argument("--repeat", type=int, help="plans per case; the median time is shown (default 1, "
                                                   "--whole-process: 3)")
    parser.add_argument("--params", metavar="FILE", help="ROS 2 parameter file for the time model")
    parser.add_argument("--chart", metavar="FILE.png", help="also draw makespan / lower bound")
    parser.add_argument(
        "--whole-process", action="store_true",
        help="time the `plan` command as a process on structure files instead (whole_process_benchmark)",
    )
    args = parser.parse_args(argv)
    whole = args.whole_process
    args.sizes = args.sizes or ([10_000] if whole else [100, 1000, 10_000])
    args.robots = args.robots or ([16] if whole else [2, 4, 8, 16])
    args.repeat = args.repeat or (3 if whole else 1)
    if min(args.sizes) < 1 or min(args.robots) < 1 or args.repeat < 1:
        print("error: sizes, robots and repeat must be at least 1", file=sys.stderr)
        return 2
    if whole:
        from planner_node.whole_process_benchmark import run_whole_process

        return run_whole_process(args.kinds, args.sizes, args.robots, max(args.repeat, 2))
    try:
        parameters = read_parameter_file(args.params)[0] if args.params else PlannerParameters()
    except ParameterError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2

    rows: list[Row] = []
    total = len(args.kinds) * len(args.sizes) * len(args.robots)
    done = 0
    started = time.perf_counter()
    try:
        for kind in args.kinds:
            for size in args.sizes:
                print(f"[{done}/{total}] generating and validating a {kind} of ~{size} tiles ...",
                      file=sys.stderr, flush=True)
                tic = time.perf_counter()
                structure = parse_structure(GENERATORS[kind](size), f"{kind}-{size}")
                load = time.perf_counter() - tic
                for robots in args.robots:
                    seconds, cpu, plans = run_case(structure, robots, parameters, args.repeat)
                    rows.append(Row(kind, size, len(structure), robots, load, seconds, cpu, plans))
                    done += 1
                    p = plans[Method.DEFAULT]
                    print(
                        f"[{done}/{total}] {kind} {len(structure)} tiles (loaded in {load:.1f} s), "
                        f"{robots} robots: "
                        f"default {p.ratio:.3f} x LB in {seconds[Method.DEFAULT]:.2f} s, "
                        f"paper {plans[Method.PAPER].ratio:.3f}, rr {plans[Method.ROUND_ROBIN].ratio:.3f}",
                        file=sys.stderr, flush=True,
                    )
    except KeyboardInterrupt:
        print("interrupted: the table shows the cases done so far", file=sys.stderr)
    if not rows:
        return 130
    print(format_table(rows))
    print()
    print(summary(rows))
    loads = {(r.kind, r.tiles): r.load_seconds for r in rows}
    print("structure generation + validation (core loader, not planning time): " + ", ".join(
        f"{k} {n}: {s:.1f} s" for (k, n), s in loads.items()
    ))
    print(f"total benchmark time {time.perf_counter() - started:.0f} s")
    if args.chart:
        draw_chart(rows, args.chart)
        print(f"chart written to {args.chart}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
