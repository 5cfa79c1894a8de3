"""`plan`: split a structure among N robots and order their tiles, without a ROS graph.

    ros2 run planner_node plan --structure FILE --robots N [--params FILE]
                               [--method default|paper|round-robin] [--format json|table]
                               [--timings]

Prints one JSON object (DESIGN.md, "planning from the command line") or, with `--format table`,
each robot's tiles in placement order with their types, like the paper's Table 1. An invalid
structure or parameter file gives one line on stderr and exit code 2.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

from planner_node.parameters import ParameterError, PlannerParameters, read_parameter_file
from planner_node.plan_format import plan_table, plan_to_json
from planner_node.planner import Method, Plan, PlanningError, default_robot_names, plan_assembly
from tiling_assembly.structure import StructureError
from tiling_assembly.structure_file import load_structure

EXIT_BAD_INPUT = 2


def _positive(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="plan", description="Split a structure among assembly robots and order their tiles."
    )
    parser.add_argument("--structure", required=True, metavar="FILE", help="structure YAML file")
    parser.add_argument("--robots", required=True, type=_positive, metavar="N", help="number of robots")
    parser.add_argument("--params", metavar="FILE", help="ROS 2 parameter file (config/planner_node.yaml)")
    parser.add_argument(
        "--method", choices=[m.value for m in Method],
        help="planning method (default: the parameter file's, else 'default')",
    )
    parser.add_argument("--format", choices=["json", "table"], default="json", help="output format")
    parser.add_argument(
        "--timings", action="store_true",
        help="also print the seconds of each stage to stderr, as 'timings: {JSON}' (for `benchmark --whole-process`)",
    )
    return parser


def seconds_since_process_start() -> float | None:
    """Wall-clock seconds since this process started (the interpreter's start and the imports
    included), from Linux's /proc at its 10 ms resolution; None elsewhere."""
    try:
        with open("/proc/self/stat", encoding="ascii") as stat:
            started_ticks = int(stat.read().rsplit(")", 1)[1].split()[19])  # field 22, after the name
        with open("/proc/uptime", encoding="ascii") as uptime:
            now = float(uptime.read().split()[0])
        return max(now - started_ticks / os.sysconf("SC_CLK_TCK"), 0.0)
    except (OSError, ValueError, IndexError):
        return None


def _print_timings(stages: dict[str, float | None], plan: Plan) -> None:
    """One line on stderr: the command's stages and the planner's own (s), rounded to the ms."""
    planner = {f"plan.{name}": seconds for name, seconds in plan.stats.seconds.items() if name != "total"}
    shown = {name: round(seconds, 3) for name, seconds in {**stages, **planner}.items() if seconds is not None}
    print(f"timings: {json.dumps(shown)}", file=sys.stderr)


def run(args: argparse.Namespace) -> int:
    parameters = PlannerParameters()
    if args.params:
        parameters, unknown = read_parameter_file(args.params)
        for name in unknown:
            print(f"warning: {args.params}: unknown parameter '{name}' ignored", file=sys.stderr)
    if parameters.robot_names and len(parameters.robot_names) != args.robots:
        raise ParameterError(
            f"{args.params}: robot_names lists {len(parameters.robot_names)} robots "
            f"but --robots is {args.robots}"
        )
    names = list(parameters.robot_names) or default_robot_names(args.robots)
    options = parameters.planning_options()
    if args.method:
        options["method"] = Method(args.method)
    started = seconds_since_process_start() if args.timings else None  # interpreter and imports
    tic = time.perf_counter()
    structure = load_structure(args.structure)
    loaded = time.perf_counter()
    plan = plan_assembly(structure, names, parameters.time_model(), **options, robot_starts=parameters.robot_starts())
    planned = time.perf_counter()
    if args.format == "table":
        print(plan_table(plan, structure))
    else:
        print(json.dumps(plan_to_json(plan)))
    sys.stdout.flush()
    if args.timings:
        stages = {"startup": started, "load": loaded - tic, "plan": planned - loaded,
                  "output": time.perf_counter() - planned}
        _print_timings(stages, plan)
    return 0


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return run(args)
    except (StructureError, ParameterError, PlanningError) as error:
        print(f"error: {error}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
