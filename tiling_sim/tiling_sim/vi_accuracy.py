"""`ros2 run tiling_sim vi_accuracy`: how well the visual inspection finds removed and misplaced tiles,
per condition of the world.

    ros2 run tiling_sim vi_accuracy [--scenes N] [--structures paper_14,gate_9] [--modes default,paper]
        [--conditions paper,world,low,low_close,robot_near] [--views 3] [--misplaced-scenes N]
        [--errors-at-bound] [--seed S] [--png FILE]

Generates random scenes as in the paper's trials (section 3): a structure part- or fully built,
1-3 tiles removed (each one nothing else rests on), the VI robot around it with its overhead pose
off by up to (or exactly, `--errors-at-bound`) 5 cm and 10 degrees. Each condition
(`inspection_scenarios.CONDITIONS`) varies what the world varies: the camera mount (high, or low
and close, where the view past a thin top-layer tile ends on grazing surfaces) and its calibration
error, the base rocking from scan to scan, localization errors at their bounds, robots standing
beside the structure (their overhead poses given to the inspection) or right in front of the
camera, loose tiles and boxes on the floor, and where grazing dropouts set in. Every scene is
scanned by the simulated Kinect and inspected in every mode, from one view and fused over up to
`--views` views (the next ones chosen by ray tracing among 12 poses around the structure, until
every tile is resolved or no pose would resolve more). Per condition and tile type (size = longest
side) the tables count removed tiles detected (missing) / undetermined (occluded, or no result
because no scan could be aligned) / called present, and present tiles called missing or misplaced,
next to the paper's figures (22 removed: 12 detected, 10 undetermined, 0 called present; 1 present
tile called missing); and the alignment: corrected camera pose against the truth. A second
experiment shifts one tile by 2-3 cm or turns it by 15-30 degrees and counts, in the default mode,
the views that see it (40 pixels or more) in which it is flagged MISPLACED, and the present tiles
flagged in error. Seeds: tune on some, report on others (`--seed`).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import time
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass, field, replace

import numpy as np

from tiling_assembly.structure import Structure
from tiling_assembly.structure_file import load_structure
from tiling_sim.inspection_scenarios import (
    CONDITIONS,
    Condition,
    Scene,
    View,
    ViewSettings,
    outline_moved,
    random_scene,
    random_view,
    ring_of_views,
    robot_in_front,
    robots_beside,
    structure_path,
)
from tiling_sim.kinect import KinectScene, KinectSimulator
from vi_node.classify import TileState
from vi_node.fusion import TileFusion, fuse_scan
from vi_node.inspection_settings import MODES, InspectionSettings
from vi_node.pipeline import InspectionPipeline
from vi_node.pose_prior import OverheadPose, pose_error
from vi_node.robot_mask import RobotBoxes
from vi_node.scan_result import ScanResult
from vi_node.viewpoint import next_viewpoint

GRAZING_BAND = math.radians(10.0)  # returns fade out over this much incidence past the onset
IN_SIGHT_PIXELS = 40  # returns a view must get of a removed tile, were it there, for the tile to be in its sight
FINE_OUTLINE = 0.01  # m: a misplacement moving the tile's outline less than this is reported apart ...
FINE_LABEL = ", outline < 1 cm"  # ... under its kind with this added


@dataclass
class Tally:
    removed: int = 0
    detected: int = 0
    undetermined: int = 0
    called_present: int = 0
    present: int = 0
    present_called_missing: int = 0
    present_called_misplaced: int = 0
    in_sight: int = 0  # fused: removed tiles one of the views taken would show, were they there ...
    in_sight_detected: int = 0  # ... and of those, the ones detected

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
    failures: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # why scans gave no states

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
            elif state in (TileState.PRESENT, TileState.MISPLACED):  # both say the tile is there
                tally.called_present += 1
            else:
                tally.undetermined += 1
        else:
            tally.present += 1
            tally.present_called_missing += state == TileState.MISSING
            tally.present_called_misplaced += state == TileState.MISPLACED


def failure_kind(reason: str) -> str:
    """A reason with its numbers replaced by N, to count alike failures together."""
    return re.sub(r"[-+]?\d+(\.\d+)?", "N", reason)[:90]


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
    if not report.pose_errors and not report.failures:  # a fused table: the scans were counted in the single-view one
        lines.append(
            f"  {report.scans} scans for these scenes ({report.scans / max(1, report.scenes):.2f} per scene)"
        )
        return "\n".join(lines)
    lines.append(alignment_line(report))
    if report.failures:
        lines.append(
            "  no states: " + "; ".join(f"{count} x {why}" for why, count in sorted(report.failures.items()))
        )
    return "\n".join(lines)


def alignment_line(report: ModeReport) -> str:
    errors = np.array(report.pose_errors) if report.pose_errors else np.zeros((0, 2))
    within = (
        float(np.mean((errors[:, 0] <= 0.01) & (errors[:, 1] <= math.radians(1.0)))) if len(errors) else 0.0
    )
    shift = float(np.median(errors[:, 0])) * 1000 if len(errors) else 0.0
    turn = math.degrees(float(np.median(errors[:, 1]))) if len(errors) else 0.0
    return (
        f"  alignment: {report.aligned}/{report.scans} scans aligned; corrected camera pose within 1 cm and "
        f"1 deg of the truth in {100 * within:.1f}% of them (median {shift:.1f} mm, {turn:.2f} deg); "
        f"median {np.median(report.seconds) * 1000 if report.seconds else 0:.0f} ms per scan"
    )


def summary_table(single: dict[tuple[str, str], ModeReport], fused: dict[tuple[str, str], ModeReport]) -> str:
    """One line per condition and mode: the figures the targets are about."""
    lines = [
        "summary (removed tiles detected; removed tiles called present; present tiles called missing;",
        f"  'in sight': removed tiles one of the fused views would show with {IN_SIGHT_PIXELS}+ returns, were they "
        "there):",
        f"  {'condition':12s}{'mode':9s}{'removed':>8s}  {'detected, 1 view':>18s}  {'detected, fused':>18s}  "
        f"{'of those in sight':>18s}  {'called present':>15s}  {'present called missing':>23s}  {'aligned':>9s}",
    ]
    for key, report in single.items():
        one, many = report.total(), fused[key].total()
        wrong = one.called_present + many.called_present
        lines.append(
            f"  {key[0]:12s}{key[1]:9s}{one.removed:8d}  {percent(one.detected, one.removed):>18s}  "
            f"{percent(many.detected, many.removed):>18s}  {percent(many.in_sight_detected, many.in_sight):>18s}  "
            f"{wrong:15d}  "
            f"{percent(one.present_called_missing + many.present_called_missing, one.present + many.present):>23s}"
            f"  {100.0 * report.aligned / max(1, report.scans):8.1f}%"
        )
    return "\n".join(lines)


def save_png(path: str, single: dict[tuple[str, str], ModeReport], fused: dict[tuple[str, str], ModeReport]) -> None:
    """Per condition and mode: removed tiles detected in one view and fused, called present, and
    present tiles called missing."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    keys = list(single)
    fig, ax = plt.subplots(figsize=(max(7.5, 1.3 * len(keys) + 2), 4.8))
    x = np.arange(len(keys))
    bars = (
        ("detected, 1 view", lambda k: _share(single[k].total().detected, single[k].total().removed), "tab:orange"),
        ("detected, fused", lambda k: _share(fused[k].total().detected, fused[k].total().removed), "tab:red"),
        ("called present", lambda k: _share(fused[k].total().called_present, fused[k].total().removed), "tab:green"),
        (
            "present called missing",
            lambda k: _share(fused[k].total().present_called_missing, fused[k].total().present),
            "tab:purple",
        ),
    )
    for offset, (name, value, colour) in enumerate(bars):
        ax.bar(x + (offset - 1.5) * 0.2, [value(k) for k in keys], 0.2, label=name, color=colour)
    ax.set_xticks(x, [f"{c}\n{m}" for c, m in keys], fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("share of removed (or present) tiles")
    ax.set_title("visual inspection per condition (simulated Kinect v1 scans)", fontsize=10)
    ax.legend(fontsize=8, loc="lower left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _share(part: int, whole: int) -> float:
    return part / whole if whole else 0.0


@dataclass
class MisplacementReport:
    views: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # kind -> views seeing one
    flagged: dict[str, int] = field(default_factory=lambda: defaultdict(int))
    otherwise: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # state name when not flagged
    present_judged: int = 0  # present tiles in views that were classified
    present_flagged: int = 0
    scenes: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # kind -> scenes seeing it at all
    caught: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # ... flagged in one of its views
    called_present: dict[str, int] = field(default_factory=lambda: defaultdict(int))  # views calling it present

    def format(self, title: str = "misplaced tiles (default mode, single views):") -> str:
        lines = [title]
        for kind in sorted(self.views):
            lines.append(
                f"  {kind:38s} views that see one: {self.views[kind]:4d}   flagged MISPLACED: "
                f"{percent(self.flagged[kind], self.views[kind])}   flagged in some view of the scene: "
                f"{self.caught[kind]}/{self.scenes[kind]}   views calling it present: {self.called_present[kind]}"
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


def misplacement_summary(reports: Iterable[MisplacementReport]) -> str:
    """Over all conditions: misplaced tiles whose outline moved at least `FINE_OUTLINE` apart from
    those that moved less (a 4 cm square turned 15 degrees: 4.5 mm), which the camera barely resolves."""
    counts = {fine: [0, 0, 0, 0, 0] for fine in (False, True)}  # caught, scenes, flagged, views, present
    for report in reports:
        for kind in report.views:
            row = counts[kind.endswith(FINE_LABEL)]
            row[0] += report.caught[kind]
            row[1] += report.scenes[kind]
            row[2] += report.flagged[kind]
            row[3] += report.views[kind]
            row[4] += report.called_present[kind]
    lines = ["misplaced tiles over all conditions (single views; a scene counts when one of its views sees the tile):"]
    for fine, (caught, scenes, flagged, views, present) in counts.items():
        what = f"outline moved < {FINE_OUTLINE * 100:g} cm" if fine else f"outline moved >= {FINE_OUTLINE * 100:g} cm"
        lines.append(
            f"  {what:24s} flagged in some view: {caught}/{scenes} scenes ({_share(caught, scenes):.1%}); "
            f"{flagged}/{views} views; views calling it present: {present}"
        )
    return "\n".join(lines)


@dataclass
class WorldDraw:
    """One scene under a condition: the scene, how its views are drawn and the sensor's grazing limit."""

    scene: Scene
    view_settings: ViewSettings
    simulator: KinectSimulator


def draw_world(
    built: Structure, condition: Condition, rng: np.random.Generator, simulator: KinectSimulator, **scene_args: object
) -> WorldDraw:
    scene = random_scene(built, rng, clutter=condition.clutter, **scene_args)  # type: ignore[arg-type]
    low, high = condition.robots_beside
    if high > 0:
        scene.robots = robots_beside(built, scene.expected, rng, int(rng.integers(low, high + 1)))
    onset = float(rng.uniform(*condition.grazing_start))
    sensor = simulator.with_noise(grazing_start=onset, grazing_end=onset + GRAZING_BAND)
    return WorldDraw(scene, condition.view_settings(rng), sensor)


class SceneRunner:
    """Scans a scene from a first view and, per mode, from the next viewpoints that mode chooses."""

    def __init__(
        self, world: WorldDraw, first: View, candidates: list[View], near_robots: list[object] | None = None
    ) -> None:
        self.world, self.first, self.candidates = world, first, candidates
        self.near_robots = near_robots  # per view index (-1 first): a robot right in front of the camera
        self._scans: dict[int, np.ndarray] = {}

    @property
    def scene(self) -> Scene:
        return self.world.scene

    def scan(self, index: int) -> tuple[View, np.ndarray]:
        """View -1 is the first one, 0.. the candidates; each scanned once, shared by every mode."""
        view = self.first if index < 0 else self.candidates[index]
        if index not in self._scans:
            physical = self.scene.kinect_scene if self.near_robots is None else self._world_seen_from(index)
            self._scans[index] = self.world.simulator.scan(physical, view.camera)
        return view, self._scans[index]

    def _world_seen_from(self, index: int, restored: tuple[int, ...] = ()) -> KinectScene:
        """The physical world of view `index` (with the robot right in front of its camera, if any),
        the `restored` removed tiles put back."""
        scene = self.scene
        tiles = [scene.structure.tiles[i] for i in (*scene.present, *restored)] + list(scene.misplaced.values())
        near = () if self.near_robots is None else (self.near_robots[index + 1],)
        return KinectScene(tiles, (*scene.clutter, *scene.robots, *near))  # type: ignore[arg-type]

    def run(
        self, pipeline: InspectionPipeline, report: ModeReport, fused_report: ModeReport, views: int
    ) -> None:
        scene = self.scene
        model = pipeline.model
        fusion = TileFusion(pipeline.evidence_settings, paper_rules=pipeline.settings.mode == "paper")
        used: list[int] = []
        index, fused = -1, ScanResult(ok=False, reason="no scan aligned")
        for count in range(views):
            view, cloud = self.scan(index)
            used.append(index)
            tick = time.perf_counter()
            robots = [OverheadPose(*r) for r in view.robots]
            result = pipeline.inspect(cloud, OverheadPose(*view.overhead), robots)
            report.seconds.append(time.perf_counter() - tick)
            report.scans += 1
            if result.ok and result.camera_pose is not None:
                report.aligned += 1
                report.pose_errors.append(pose_error(result.camera_pose, view.camera))
            elif not result.ok:
                report.failures[failure_kind(result.reason)] += 1
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
                robots=RobotBoxes(robots, pipeline.robot_settings),
            )
            if choice is None:
                break
            index = free[[OverheadPose(*self.candidates[k].overhead) for k in free].index(choice.pose)]
        fused_report.scans += len(used)
        fused_report.scenes += 1
        score(scene.structure, set(scene.removed), scene.expected, fused, fused_report)
        self._score_in_sight(used, fused, fused_report)

    def _score_in_sight(self, used: list[int], fused: ScanResult, report: ModeReport) -> None:
        """Which removed tiles one of the views `used` would show with `IN_SIGHT_PIXELS` returns or
        more, were they there, and which of those the views found: a tile behind a box nobody
        reports, or a robot right in front of the camera, is out of every view's sight."""
        scene, states = self.scene, (fused.by_id() if fused.ok else {})
        for tile_id in scene.removed:
            shown = max(
                self.world.simulator.pixels_showing(
                    self._world_seen_from(index, (tile_id,)),
                    (self.first if index < 0 else self.candidates[index]).camera,
                    tile_id,
                )
                for index in used
            )
            if shown < IN_SIGHT_PIXELS:
                continue
            tally = report.by_type[type_label(scene.structure, scene.structure.tiles[tile_id].type_name)]
            tally.in_sight += 1
            tally.in_sight_detected += tile_id in states and states[tile_id].state == TileState.MISSING


def misplacement_trial(
    built: Structure,
    rng: np.random.Generator,
    simulator: KinectSimulator,
    pipeline: InspectionPipeline,
    report: MisplacementReport,
    condition: Condition,
    views: int = 3,
) -> None:
    """One scene with a tile shifted 2-5 cm, turned 15-45 degrees or of the wrong type (the faults of
    `tiling_sim.faults`); every view judged alone."""
    kind = str(rng.choice(["shift", "turn", "wrong_type"]))
    world = draw_world(
        built, replace(condition, clutter=0.0), rng, simulator, removals=(0, 1), partial=0.3, misplacements=1,
        misplace_kind=kind,
    )
    scene = world.scene
    if not scene.misplaced:
        return
    moved = next(iter(scene.misplaced))
    how = {"shift": "shifted 2-5 cm", "turn": "turned 15-45 deg", "wrong_type": "of the wrong type"}[kind]
    if outline_moved(built.tiles[moved], scene.misplaced[moved]) < FINE_OUTLINE:
        how += FINE_LABEL
    label = f"{type_label(built, built.tiles[moved].type_name)} {how}"
    pipeline.set_expected(scene.expected)
    seen = flagged = False
    for _ in range(views):
        view = random_view(scene.centre, rng, world.view_settings, scene.robots, scene.unreported)
        cloud, labels = world.simulator.scan_labelled(scene.kinect_scene, view.camera)
        result = pipeline.inspect(cloud, OverheadPose(*view.overhead), [OverheadPose(*r) for r in view.robots])
        if not result.ok:
            continue
        states = result.by_id()
        for tile_id in scene.present:
            report.present_judged += 1
            report.present_flagged += states[tile_id].state == TileState.MISPLACED
        if int(np.count_nonzero(labels == moved)) < 40:
            continue  # this view does not see the misplaced tile
        report.views[label] += 1
        seen = True
        if states[moved].state == TileState.MISPLACED:
            report.flagged[label] += 1
            flagged = True
        else:
            report.otherwise[states[moved].state.label] += 1
            report.called_present[label] += states[moved].state == TileState.PRESENT
    report.scenes[label] += seen
    report.caught[label] += flagged


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="ros2 run tiling_sim vi_accuracy", description=__doc__.split("\n\n")[0])
    parser.add_argument("--scenes", type=int, default=30, help="scenes per structure and condition")
    parser.add_argument(
        "--structures", default="paper_14,gate_9", help="structure names in config/structures or paths"
    )
    parser.add_argument("--modes", default=",".join(MODES), help="inspection modes to compare")
    parser.add_argument(
        "--conditions", default=",".join(CONDITIONS), help=f"conditions of the world ({', '.join(CONDITIONS)})"
    )
    parser.add_argument(
        "--views", type=int, default=3, help="views fused at most per scene (1: single view only)"
    )
    parser.add_argument(
        "--misplaced-scenes", type=int, default=10, help="scenes with a misplaced tile, per structure and condition"
    )
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--png", default="", help="also draw the summary as a picture")
    parser.add_argument(
        "--errors-at-bound",
        action="store_true",
        help="overhead errors exactly 5 cm and 10 degrees in every condition",
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    modes = [m for m in args.modes.split(",") if m]
    conditions = [c for c in args.conditions.split(",") if c]
    unknown = [m for m in modes if m not in MODES] + [c for c in conditions if c not in CONDITIONS]
    if unknown or args.scenes < 1 or args.views < 1 or args.misplaced_scenes < 0:
        print(
            f"error: unknown mode(s) or condition(s) {', '.join(unknown)} (modes: {', '.join(MODES)}; "
            f"conditions: {', '.join(CONDITIONS)})"
            if unknown
            else "error: --scenes and --views must be at least 1, --misplaced-scenes not negative",
            file=sys.stderr,
        )
        return 2
    structures = [load_structure(structure_path(name)) for name in args.structures.split(",") if name]
    single: dict[tuple[str, str], ModeReport] = {}
    fused: dict[tuple[str, str], ModeReport] = {}
    misplaced: dict[str, MisplacementReport] = {}
    rng = np.random.default_rng(args.seed)
    simulator = KinectSimulator(seed=args.seed)
    started = time.monotonic()
    per_structure = args.scenes + (args.misplaced_scenes if "default" in modes else 0)
    total = per_structure * len(structures) * len(conditions)
    done = 0

    def progress() -> None:
        if done % 10 == 0 or done == total:
            print(f"  {done}/{total} scenes ({time.monotonic() - started:.0f} s)", file=sys.stderr, flush=True)

    for name in conditions:
        condition = CONDITIONS[name]
        if args.errors_at_bound:
            condition = replace(condition, errors_at_bound=True)
        settings = InspectionSettings().with_values(
            {"camera_xyz": list(condition.mount[0]), "camera_rpy": list(condition.mount[1])}
        )
        for mode in modes:
            single[(name, mode)], fused[(name, mode)] = ModeReport(), ModeReport()
        misplaced[name] = MisplacementReport()
        for built in structures:
            pipelines = {m: InspectionPipeline(built, None, settings.with_values({"mode": m})) for m in modes}
            for _ in range(args.scenes):
                runner = scene_runner(built, condition, rng, simulator)
                for mode, pipeline in pipelines.items():
                    pipeline.set_expected(runner.scene.expected)
                    runner.run(pipeline, single[(name, mode)], fused[(name, mode)], args.views)
                done += 1
                progress()
            if "default" in pipelines:
                for _ in range(args.misplaced_scenes):
                    misplacement_trial(built, rng, simulator, pipelines["default"], misplaced[name], condition)
                    done += 1
                    progress()
    print_report(args, structures, conditions, modes, single, fused, misplaced)
    if args.png:
        save_png(args.png, single, fused)
        print(f"\npicture: {args.png}")
    return 0


def scene_runner(
    built: Structure, condition: Condition, rng: np.random.Generator, simulator: KinectSimulator
) -> SceneRunner:
    world = draw_world(built, condition, rng, simulator)
    scene, views = world.scene, world.view_settings
    first = random_view(scene.centre, rng, views, scene.robots, scene.unreported)
    distance = float(rng.uniform(*condition.distance))
    ring = ring_of_views(scene.centre, rng, 12, distance, views, scene.robots, scene.unreported)
    near = [robot_in_front(v, rng) for v in (first, *ring)] if condition.robot_near_camera else None
    return SceneRunner(world, first, ring, near)  # type: ignore[arg-type]


def print_report(
    args: argparse.Namespace,
    structures: list[Structure],
    conditions: list[str],
    modes: list[str],
    single: dict[tuple[str, str], ModeReport],
    fused: dict[tuple[str, str], ModeReport],
    misplaced: dict[str, MisplacementReport],
) -> None:
    print(
        f"Visual inspection on simulated Kinect v1 scans (640x480), seed {args.seed}: {args.scenes} scenes each of "
        f"{', '.join(s.name for s in structures)} per condition; 1-3 tiles removed per scene"
    )
    for name in conditions:
        print(f"\n== condition {name}: {CONDITIONS[name].description}")
        for mode in modes:
            print()
            print(format_table(f"mode {mode}, single view", single[(name, mode)]))
            if args.views > 1:
                how = "evidence summed per tile" if mode == "default" else "latest resolved state per tile"
                print()
                print(
                    format_table(
                        f"mode {mode}, fused over up to {args.views} views (next viewpoints by ray tracing; {how})",
                        fused[(name, mode)],
                    )
                )
        if "default" in modes and args.misplaced_scenes:
            print()
            print(misplaced[name].format())
    print()
    print(summary_table(single, fused))
    if "default" in modes and args.misplaced_scenes:
        print()
        print(misplacement_summary(misplaced.values()))


if __name__ == "__main__":
    sys.exit(main())
