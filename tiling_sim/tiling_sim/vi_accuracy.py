"""`ros2 run tiling_sim vi_accuracy`: how well the visual inspection finds removed and misplaced tiles.

    ros2 run tiling_sim vi_accuracy [--scenes N] [--structures paper_14,gate_9] [--modes default,paper]
        [--views 3] [--misplaced-scenes N] [--errors-at-bound] [--seed S] [--png FILE]

Generates random scenes as in the paper's trials (section 3): a structure part- or fully built,
1-3 tiles removed (each one nothing else rests on), sometimes another robot and a loose tile
nearby; the VI robot 0.8-1.5 m away, its overhead pose off by up to 5 cm and 10 degrees (uniform).
Every scene is scanned by the simulated Kinect and inspected in every mode, from one view and
fused over up to `--views` views (the next ones chosen by ray tracing among 12 poses around the
structure, until every tile is resolved or no pose would resolve more). Per tile type (size =
longest side) the tables count removed tiles detected (missing) / undetermined (occluded, or no
result because no scan could be aligned) / called present, and present tiles called missing or
misplaced, next to the paper's figures (22 removed: 12 detected, 10 undetermined, 0 called
present; 1 present tile called missing); and the alignment: corrected camera pose against the
truth. A second experiment shifts one tile by 2-3 cm or turns it by 15-30 degrees and counts, in
the default mode, the views that see it (40 pixels or more) in which it is flagged MISPLACED, and
the present tiles flagged in error.
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
from tiling_sim.inspection_scenarios import (
    Scene,
    View,
    ViewSettings,
    random_scene,
    random_view,
    ring_of_views,
    structure_path,
)
from tiling_sim.kinect import KinectSimulator
from vi_node.classify import TileState
from vi_node.fusion import TileFusion, fuse_scan
from vi_node.inspection_settings import MODES, InspectionSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_prior import OverheadPose, pose_error
from vi_node.scan_result import ScanResult
from vi_node.viewpoint import next_viewpoint


@dataclass
class Tally:
    removed: int = 0
    detected: int = 0
    undetermined: int = 0
    called_present: int = 0
    present: int = 0
    present_called_missing: int = 0
    present_called_misplaced: int = 0

    def add(self, other: Tally) -> None:
        for name in vars(self):
            setattr(self, name, getattr(self, name) + getattr(other, name))


@dataclass
class ModeReport:
    by_type: dict[str, Tally] = field(default_factory=lambda: defaultdict(Tally))
    scans: int = 0
    aligned: int = 0
    pose_errors: list[tuple[float, float]] = field(default_factory=list)
    scenes: int = 0
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
            tally.present_called_misplaced += state == TileState.MISPLACED


def percent(part: int, whole: int) -> str:
    return f"{part:4d} ({100.0 * part / whole:5.1f}%)" if whole else f"{part:4d}   (  -  )"


def format_table(title: str, report: ModeReport) -> str:
    lines = [
        title,
        f"  {'tile type (size)':24s}{'removed':>8s}  {'detected':>14s}  {'undetermined':>14s}  "
        f"{'called present':>14s}  {'present':>8s}  {'called missing':>14s}  {'misplaced':>14s}",
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
            + f"  {percent(t.present_called_misplaced, t.present):>14s}"
        )
    lines.append(
        f"  {'paper (Worcester et al.)':24s}{22:8d}  {percent(12, 22):>14s}  {percent(10, 22):>14s}  "
        f"{percent(0, 22):>14s}  {'-':>8s}  {'   1':>14s}"
    )
    if not report.pose_errors:  # a fused table: the scans were counted in the single-view one
        lines.append(
            f"  {report.scans} scans for these scenes ({report.scans / max(1, report.scenes):.2f} per scene)"
        )
        return "\n".join(lines)
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

    columns = min(2, len(reports))
    rows = math.ceil(len(reports) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(7.5 * columns, 4.8 * rows), squeeze=False)
    for ax in axes.flat[len(reports) :]:
        ax.set_visible(False)
    for ax, (title, report) in zip(axes.flat, reports.items(), strict=False):
        title = title.replace(" (next", "\n(next")
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


@dataclass
class MisplacementReport:
    views: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # kind -> views seeing one
    flagged: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    otherwise: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # state name when not flagged
    present_judged: int = 0  # present tiles in views that were classified
    present_flagged: int = 0

    def format(self) -> str:
        lines = ["misplaced tiles (default mode, single views):"]
        for kind in sorted(self.views):
            lines.append(
                f"  {kind:38s} views that see one: {self.views[kind]:4d}   flagged MISPLACED: "
                f"{percent(self.flagged[kind], self.views[kind])}"
            )
        if self.otherwise:
            lines.append(
                "  not flagged, reported as: "
                + ", ".join(f"{k} {v}" for k, v in sorted(self.otherwise.items()))
            )
        lines.append(
            f"  present tiles flagged MISPLACED: {percent(self.present_flagged, self.present_judged)} of "
            f"{self.present_judged} present tiles in those views"
        )
        return "\n".join(lines)


class SceneRunner:
    """Scans a scene from a first view and, per mode, from the next viewpoints that mode chooses."""

    def __init__(self, simulator: KinectSimulator, scene: Scene, first: View, candidates: list[View]) -> None:
        self.simulator, self.scene, self.first, self.candidates = simulator, scene, first, candidates
        self._scans: dict[int, np.ndarray] = {}

    def scan(self, index: int) -> tuple[View, np.ndarray]:
        """View -1 is the first one, 0.. the candidates; each scanned once, shared by every mode."""
        view = self.first if index < 0 else self.candidates[index]
        if index not in self._scans:
            self._scans[index] = self.simulator.scan(self.scene.kinect_scene, view.camera)
        return view, self._scans[index]

    def run(
        self, pipeline: InspectionPipeline, report: ModeReport, fused_report: ModeReport, views: int
    ) -> None:
        scene = self.scene
        model = pipeline.model
        fusion = TileFusion(pipeline.evidence_settings, paper_rules=pipeline.settings.mode == "paper")
        used: list[int] = []
        index, fused = -1, ScanResult(False, "no scan aligned")
        for count in range(views):
            view, cloud = self.scan(index)
            used.append(index)
            tick = time.perf_counter()
            result = pipeline.inspect(cloud, OverheadPose(*view.overhead))
            report.seconds.append(time.perf_counter() - tick)
            report.scans += 1
            if result.ok and result.camera_pose is not None:
                report.aligned += 1
                report.pose_errors.append(pose_error(result.camera_pose, view.camera))
            if count == 0:
                score(scene.structure, set(scene.removed), scene.expected, result, report)
            if result.ok:
                fused = fuse_scan(fusion, result)
            unresolved = fusion.unresolved(scene.expected)
            free = [k for k in range(len(self.candidates)) if k not in used]
            if count + 1 >= views or not unresolved or not free:
                break
            choice = next_viewpoint(
                model.scene,
                model.low,
                model.high,
                pipeline.camera,
                pipeline.mount,
                [OverheadPose(*self.candidates[k].overhead) for k in free],
                unresolved,
                current=OverheadPose(*view.overhead),
                settings=pipeline.evidence_settings,
            )
            if choice is None:
                break
            index = free[[OverheadPose(*self.candidates[k].overhead) for k in free].index(choice.pose)]
        fused_report.scans += len(used)
        fused_report.scenes += 1
        score(scene.structure, set(scene.removed), scene.expected, fused, fused_report)


def misplacement_trial(
    built: Structure,
    rng: np.random.Generator,
    simulator: KinectSimulator,
    pipeline: InspectionPipeline,
    report: MisplacementReport,
    view_settings: ViewSettings,
    views: int = 3,
) -> None:
    """One scene with a tile shifted 2-3 cm or turned 15-30 degrees; every view judged alone."""
    kind = str(rng.choice(["shift", "turn"]))
    scene = random_scene(
        built, rng, removals=(0, 1), partial=0.3, clutter=0.0, misplacements=1, misplace_kind=kind
    )
    if not scene.misplaced:
        return
    moved = next(iter(scene.misplaced))
    how = "shifted 2-3 cm" if kind == "shift" else "turned 15-30 deg"
    label = f"{type_label(built, built.tiles[moved].type_name)} {how}"
    pipeline.set_expected(scene.expected)
    for _ in range(views):
        view = random_view(scene.centre, rng, view_settings)
        cloud, labels = simulator.scan_labelled(scene.kinect_scene, view.camera)
        result = pipeline.inspect(cloud, OverheadPose(*view.overhead))
        if not result.ok:
            continue
        states = result.by_id()
        for tile_id in scene.present:
            report.present_judged += 1
            report.present_flagged += states[tile_id].state == TileState.MISPLACED
        if int(np.count_nonzero(labels == moved)) < 40:
            continue  # this view does not see the misplaced tile
        report.views[label] += 1
        if states[moved].state == TileState.MISPLACED:
            report.flagged[label] += 1
        else:
            report.otherwise[states[moved].state.label] += 1


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="ros2 run tiling_sim vi_accuracy", description=__doc__.split("\n\n")[0]
    )
    parser.add_argument("--scenes", type=int, default=60, help="scenes per structure")
    parser.add_argument(
        "--structures", default="paper_14,gate_9", help="structure names in config/structures or paths"
    )
    parser.add_argument("--modes", default=",".join(MODES), help="inspection modes to compare")
    parser.add_argument(
        "--views", type=int, default=3, help="views fused at most per scene (1: single view only)"
    )
    parser.add_argument(
        "--misplaced-scenes", type=int, default=20, help="scenes with a misplaced tile, per structure"
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--png", default="", help="also draw the tables as a picture")
    parser.add_argument(
        "--errors-at-bound",
        action="store_true",
        help="overhead errors exactly 5 cm and 10 degrees (default: uniform up to those)",
    )
    args = parser.parse_args(argv)
    modes = [m for m in args.modes.split(",") if m]
    unknown = [m for m in modes if m not in MODES]
    if unknown or args.scenes < 1 or args.views < 1 or args.misplaced_scenes < 0:
        print(
            f"error: unknown mode(s) {', '.join(unknown)} (known: {', '.join(MODES)})"
            if unknown
            else "error: --scenes and --views must be at least 1, --misplaced-scenes not negative",
            file=sys.stderr,
        )
        return 2
    structures = [load_structure(structure_path(name)) for name in args.structures.split(",") if name]
    single = {mode: ModeReport() for mode in modes}
    fused = {mode: ModeReport() for mode in modes}
    misplaced = MisplacementReport()
    view_settings = ViewSettings(errors_at_bound=args.errors_at_bound)
    rng = np.random.default_rng(args.seed)
    simulator = KinectSimulator(seed=args.seed)
    started = time.monotonic()
    total = (args.scenes + (args.misplaced_scenes if "default" in modes else 0)) * len(structures)
    done = 0

    def progress() -> None:
        if done % 10 == 0 or done == total:
            print(
                f"  {done}/{total} scenes ({time.monotonic() - started:.0f} s)", file=sys.stderr, flush=True
            )

    for built in structures:
        pipelines = {
            m: InspectionPipeline(built, None, InspectionSettings().with_values({"mode": m})) for m in modes
        }
        for _ in range(args.scenes):
            scene = random_scene(built, rng)
            first = random_view(scene.centre, rng, view_settings)
            ring = ring_of_views(scene.centre, rng, 12, float(rng.uniform(0.9, 1.3)), view_settings)
            runner = SceneRunner(simulator, scene, first, ring)
            for mode, pipeline in pipelines.items():
                pipeline.set_expected(scene.expected)
                runner.run(pipeline, single[mode], fused[mode], args.views)
            done += 1
            progress()
        if "default" in pipelines:
            for _ in range(args.misplaced_scenes):
                misplacement_trial(built, rng, simulator, pipelines["default"], misplaced, view_settings)
                done += 1
                progress()
    errors = (
        "overhead errors of exactly 5 cm and 10 deg"
        if args.errors_at_bound
        else "overhead errors up to 5 cm / 10 deg"
    )
    print(
        f"Visual inspection on simulated Kinect v1 scans (640x480): {args.scenes} scenes each of "
        f"{', '.join(s.name for s in structures)}; 1-3 tiles removed per scene; VI robot 0.8-1.5 m away; "
        + errors
    )
    tables: dict[str, ModeReport] = {}
    for mode in modes:
        tables[f"mode {mode}, single view"] = single[mode]
        if args.views > 1:
            how = "evidence summed per tile" if mode == "default" else "latest resolved state per tile"
            tables[
                f"mode {mode}, fused over up to {args.views} views (next viewpoints by ray tracing; {how})"
            ] = fused[mode]
    for title, report in tables.items():
        print()
        print(format_table(title, report))
    if "default" in modes and args.misplaced_scenes:
        print()
        print(misplaced.format())
    if args.png:
        save_png(args.png, tables)
        print(f"\npicture: {args.png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
