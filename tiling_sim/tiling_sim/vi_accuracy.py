"""`ros2 run tiling_sim vi_accuracy`: how well the visual inspection finds removed tiles.

    ros2 run tiling_sim vi_accuracy [--scenes N] [--structures paper_14,gate_9] [--modes paper]
        [--seed S] [--png FILE]

Generates random scenes as in the paper's trials (section 3): a structure part- or fully built,
1-3 tiles removed (each one nothing else rests on), sometimes another robot and a loose tile
nearby; the VI robot 0.8-1.5 m away, its overhead pose off by up to 5 cm and 10 degrees (uniform).
Every scene is scanned by the simulated Kinect and inspected; the table counts, per tile type
(size = longest side), removed tiles detected (missing) / undetermined (occluded, or no result
because the scan could not be aligned) / called present, and present tiles called missing, next
to the paper's figures (22 removed: 12 detected, 10 undetermined, 0 called present; 1 present
tile called missing). Also the alignment: the corrected camera pose against the truth.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections import defaultdict
from dataclasses import dataclass, field

import numpy as np

from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import load_structure
from tiling_sim.inspection_scenarios import ViewSettings, random_scene, random_view, structure_path
from tiling_sim.kinect import KinectSimulator
from vi_node.classify import TileState
from vi_node.inspection_settings import MODES, InspectionSettings
from vi_node.pipeline import InspectionPipeline, ScanResult
from vi_node.pose_prior import OverheadPose, pose_error


@dataclass
class Tally:
    removed: int = 0
    detected: int = 0
    undetermined: int = 0
    called_present: int = 0
    present: int = 0
    present_called_missing: int = 0

    def add(self, other: Tally) -> None:
        for name in vars(self):
            setattr(self, name, getattr(self, name) + getattr(other, name))


@dataclass
class ModeReport:
    by_type: dict[str, Tally] = field(default_factory=lambda: defaultdict(Tally))
    scans: int = 0
    aligned: int = 0
    pose_errors: list[tuple[float, float]] = field(default_factory=list)
    seconds: list[float] = field(default_factory=list)

    def total(self) -> Tally:
        total = Tally()
        for tally in self.by_type.values():
            total.add(tally)
        return total


def type_label(structure: Structure, type_name: str) -> str:
    vertices = structure.tile_types[type_name].shape.vertices
    size = float(np.ptp(vertices[:, :2], axis=0).max())
    return f"{type_name} ({size * 100:.0f} cm)"


def score(
    structure: Structure, removed: set[int], expected: tuple[int, ...], result: ScanResult, report: ModeReport
) -> None:
    """Add one judged scene (one scan, or several fused) to the report."""
    states = result.by_id() if result.ok else {}
    for tile_id in expected:
        tally = report.by_type[type_label(structure, structure.tiles[tile_id].type_name)]
        state = states[tile_id].state if tile_id in states else TileState.OCCLUDED
        if tile_id in removed:
            tally.removed += 1
            if state == TileState.MISSING:
                tally.detected += 1
            elif state == TileState.PRESENT:
                tally.called_present += 1
            else:
                tally.undetermined += 1
        else:
            tally.present += 1
            tally.present_called_missing += state == TileState.MISSING


def percent(part: int, whole: int) -> str:
    return f"{part:4d} ({100.0 * part / whole:5.1f}%)" if whole else f"{part:4d}   (  -  )"


def format_table(title: str, report: ModeReport) -> str:
    lines = [
        title,
        f"  {'tile type (size)':24s}{'removed':>8s}  {'detected':>14s}  {'undetermined':>14s}  "
        f"{'called present':>14s}  {'present':>8s}  {'called missing':>14s}",
    ]
    rows = sorted(report.by_type.items(), key=lambda kv: kv[0])
    for label, t in [*rows, ("all", report.total())]:
        cells = [
            percent(t.detected, t.removed),
            percent(t.undetermined, t.removed),
            percent(t.called_present, t.removed),
        ]
        lines.append(
            f"  {label:24s}{t.removed:8d}  "
            + "  ".join(f"{c:>14s}" for c in cells)
            + f"  {t.present:8d}  {percent(t.present_called_missing, t.present):>14s}"
        )
    lines.append(
        f"  {'paper (Worcester et al.)':24s}{22:8d}  {percent(12, 22):>14s}  {percent(10, 22):>14s}  "
        f"{percent(0, 22):>14s}  {'-':>8s}  {'   1':>14s}"
    )
    errors = np.array(report.pose_errors) if report.pose_errors else np.zeros((0, 2))
    within = (
        float(np.mean((errors[:, 0] <= 0.01) & (errors[:, 1] <= math.radians(1.0)))) if len(errors) else 0.0
    )
    shift = float(np.median(errors[:, 0])) * 1000 if len(errors) else 0.0
    turn = math.degrees(float(np.median(errors[:, 1]))) if len(errors) else 0.0
    lines.append(
        f"  alignment: {report.aligned}/{report.scans} scans aligned; corrected camera pose within 1 cm and "
        f"1 deg of the truth in {100 * within:.1f}% of them (median {shift:.1f} mm, {turn:.2f} deg); "
        f"median {np.median(report.seconds) * 1000 if report.seconds else 0:.0f} ms per scan"
    )
    return "\n".join(lines)


def save_png(path: str, reports: dict[str, ModeReport]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(reports), figsize=(6 * len(reports), 4.5), squeeze=False)
    for ax, (title, report) in zip(axes[0], reports.items(), strict=True):
        labels = sorted(report.by_type)
        tallies = [report.by_type[k] for k in labels]
        x = np.arange(len(labels))
        for offset, (name, key, colour) in enumerate(
            (
                ("detected", "detected", "tab:red"),
                ("undetermined", "undetermined", "gold"),
                ("called present", "called_present", "tab:green"),
            )
        ):
            values = [getattr(t, key) / t.removed if t.removed else 0 for t in tallies]
            ax.bar(x + (offset - 1.5) * 0.2, values, 0.2, label=name, color=colour)
        wrong = [t.present_called_missing / t.present if t.present else 0 for t in tallies]
        ax.bar(x + 1.5 * 0.2, wrong, 0.2, label="present called missing (of present)", color="tab:purple")
        ax.set_xticks(x, labels, rotation=30, ha="right", fontsize=8)
        ax.set_ylim(0, 1)
        ax.set_ylabel("share of removed (or present) tiles")
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="ros2 run tiling_sim vi_accuracy", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--scenes", type=int, default=60, help="scenes per structure")
    parser.add_argument(
        "--structures", default="paper_14,gate_9", help="structure names in config/structures or paths"
    )
    parser.add_argument("--modes", default=",".join(MODES), help="inspection modes to compare")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--png", default="", help="also draw the table as a picture")
    parser.add_argument(
        "--errors-at-bound",
        action="store_true",
        help="overhead errors exactly 5 cm and 10 degrees (default: uniform up to those)",
    )
    args = parser.parse_args(argv)
    modes = [m for m in args.modes.split(",") if m]
    unknown = [m for m in modes if m not in MODES]
    if unknown or args.scenes < 1:
        print(
            f"error: unknown mode(s) {', '.join(unknown)} (known: {', '.join(MODES)})"
            if unknown
            else "error: --scenes must be at least 1",
            file=sys.stderr,
        )
        return 2
    structures = []
    for name in (n for n in args.structures.split(",") if n):
        structures.append(load_structure(structure_path(name)))
    reports = {mode: ModeReport() for mode in modes}
    view_settings = ViewSettings(errors_at_bound=args.errors_at_bound)
    rng = np.random.default_rng(args.seed)
    simulator = KinectSimulator(seed=args.seed)
    started = time.monotonic()
    total = args.scenes * len(structures)
    done = 0
    for built in structures:
        pipelines = {
            mode: InspectionPipeline(built, None, InspectionSettings().with_values({"mode": mode}))
            for mode in modes
        }
        for _ in range(args.scenes):
            scene = random_scene(built, rng)
            view = random_view(scene.centre, rng, view_settings)
            cloud = simulator.scan(scene.kinect_scene, view.camera)
            for mode, pipeline in pipelines.items():
                pipeline.set_expected(scene.expected)
                tick = time.perf_counter()
                result = pipeline.inspect(cloud, OverheadPose(*view.overhead))
                report = reports[mode]
                report.seconds.append(time.perf_counter() - tick)
                report.scans += 1
                if result.ok and result.camera_pose is not None:
                    report.aligned += 1
                    report.pose_errors.append(pose_error(result.camera_pose, view.camera))
                score(built, set(scene.removed), scene.expected, result, report)
            done += 1
            if done % 10 == 0 or done == total:
                print(
                    f"  {done}/{total} scenes ({time.monotonic() - started:.0f} s)",
                    file=sys.stderr,
                    flush=True,
                )
    print(
        f"Visual inspection on simulated Kinect v1 scans: {args.scenes} scenes each of "
        f"{', '.join(s.name for s in structures)}; 1-3 tiles removed per scene; "
        + (
            "overhead errors of exactly 5 cm and 10 deg"
            if args.errors_at_bound
            else "overhead errors up to 5 cm / 10 deg"
        )
    )
    for mode, report in reports.items():
        print()
        print(format_table(f"mode {mode}, single view", report))
    if args.png:
        save_png(args.png, {f"{mode}, single view": r for mode, r in reports.items()})
        print(f"\npicture: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
