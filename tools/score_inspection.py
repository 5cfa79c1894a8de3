#!/usr/bin/env python3
"""Score `ros2 run vi_node classify` on the scenes of `tools/independent_scenes.py`, as a user runs it.

    tools/workspace-env python tools/score_inspection.py --scenes DIR [--views 3] [--params FILE]
        [--json OUT] [--ros2 "CMD"] [--sets NAME,...] [--classify-arg ARG ...]

For every scene folder under DIR (a rosbag2 folder with `truth.json`) the real command runs twice
as a subprocess, with the nominal mount of the scene's set and S_a = the tiles claimed placed:

    ros2 run vi_node classify --structure S --bag B --expected IDS --camera-xyz X,Y,Z --camera-rpy R,P,Y --no-fuse
    ros2 run vi_node classify ... (fused: the line of scan k is the state after scans 1..k)

and its JSON lines are compared with the truth. Tallies per scene set and per tile type:

- removed tiles: detected ("missing") / undetermined ("occluded", not reported, or the scan
  failed) / called present ("present" or "misplaced": both say the tile is there); also among the
  removed tiles a scan could have seen ("visible": >= 40 pixels of it in a render of the expected
  structure that would surely give returns: in range, incidence below the grazing onset);
- present tiles (at their planned pose): called missing, called misplaced;
- misplaced tiles, by kind: flagged "misplaced" in some single view among the views that see it
  (>= 40 pixels with a return on it), scans calling it present, scans calling it missing, and the
  fused state; a turned tile whose turn lies within 15 degrees of one that maps its shape onto
  itself (an octagon turned 40 degrees) is kind "turn_onto_symmetry", not "turn";
- failed scans (an "error" key, or no line for the scan) per set, and among the scans whose truth
  shows S_a (>= 60 returns on its tiles; fewer leave nothing to align on, so failing there is right).

Single views: every one of the first --views scans on its own (unit: tile x scan). Fused: the
state after the last of the first --views scans (unit: tile); when that scan failed, the last fused
state printed before it. Wall time of the whole classify process per bag and per scan (median).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import shlex
import statistics
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

from one_line_errors import InputError, OneLineParser, run_command

REPO = Path(__file__).resolve().parent.parent
SEEN_PIXELS = 40  # a scan "sees" a tile with at least this many pixels of it
# a scan shows S_a with at least this many returns on its tiles (vi_node's min_alignment_points):
# below it no alignment is possible, and a failure is no fault of the alignment
SA_SHOWN_RETURNS = 60
LEAST_TURN_DEG = 15.0  # a turn the issue asks to flag; an octagon turned 40 degrees is turned 5 (its symmetry)
ALL = "all"


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(prog="score_inspection.py", description="Score vi_node classify on independent scenes.")
    p.add_argument("--scenes", required=True, help="folder of scenes (searched recursively for truth.json)")
    p.add_argument("--views", type=int, default=3, help="use the first this many scans of every bag (default 3)")
    p.add_argument("--params", default=None, help="parameter file passed to classify (--params)")
    p.add_argument("--json", default=None, help="write every tally to this file")
    p.add_argument("--classify-arg", nargs=argparse.REMAINDER, default=[], metavar="ARG",
                   help="every argument after this one goes to classify (last; e.g. --classify-arg --mode paper)")
    p.add_argument("--ros2", default=f"{REPO / 'tools' / 'workspace-env'} ros2",
                   help="the ros2 command (default: tools/workspace-env ros2)")
    p.add_argument("--sets", default="all", help="only these scene sets (comma-separated; default all)")
    p.add_argument("--timeout", type=float, default=600.0, help="seconds per classify run (default 600)")
    return p


# --- running classify --------------------------------------------------------------------------

def find_scenes(root: Path, sets: set[str] | None) -> list[tuple[Path, dict[str, Any]]]:
    scenes = []
    for truth_file in sorted(root.rglob("truth.json")):
        try:
            truth = json.loads(truth_file.read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as error:
            raise InputError(f"{truth_file}: unreadable truth: {error}") from None
        if sets is None or truth.get("set") in sets:
            scenes.append((truth_file.parent, truth))
    return scenes


def structure_path(truth: dict[str, Any]) -> str:
    path = Path(truth["structure"])
    return str(path if path.is_absolute() else REPO / path)


def classify_command(ros2: list[str], folder: Path, truth: dict[str, Any], args: argparse.Namespace,
                     fuse: bool) -> list[str]:
    xyz, rpy = truth["nominal_mount"]["xyz"], truth["nominal_mount"]["rpy"]
    command = [*ros2, "run", "vi_node", "classify", "--structure", structure_path(truth), "--bag", str(folder),
               "--expected", ",".join(str(t) for t in truth["expected"]),
               "--camera-xyz", ",".join(repr(float(v)) for v in xyz),
               "--camera-rpy", ",".join(repr(float(v)) for v in rpy)]
    if args.params:
        command += ["--params", args.params]
    if not fuse:
        command.append("--no-fuse")
    return command + list(args.classify_arg)


def run_classify(command: list[str], timeout: float) -> tuple[list[dict[str, Any]], str, int, float]:
    start = time.monotonic()
    try:
        proc = subprocess.run(command, capture_output=True, text=True, timeout=timeout, cwd=REPO)
    except subprocess.TimeoutExpired:
        return [], f"timed out after {timeout:g} s", -1, time.monotonic() - start
    except OSError as error:
        return [], f"cannot run {command[0]}: {error}", -1, time.monotonic() - start
    wall = time.monotonic() - start
    lines = []
    for line in proc.stdout.splitlines():
        line = line.strip()
        if line.startswith("{"):
            try:
                lines.append(json.loads(line))
            except json.JSONDecodeError:
                continue
    return lines, proc.stderr, proc.returncode, wall


def per_scan(lines: list[dict[str, Any]], truth: dict[str, Any], views: int) -> list[dict[str, Any] | None]:
    """The output line of each of the first `views` scans (None: no line for it)."""
    by_stamp = {round(float(line.get("stamp", -1)), 3): line for line in lines}
    out: list[dict[str, Any] | None] = []
    for k, scan in enumerate(truth["scans"][:views]):
        line = by_stamp.get(round(float(scan["stamp"]), 3))
        if line is None and len(lines) == len(truth["scans"]):
            line = lines[k]
        out.append(line)
    return out


# --- tallies -----------------------------------------------------------------------------------

def state_of(line: dict[str, Any] | None, tile: int) -> str:
    """'missing', 'present', 'misplaced', 'occluded', 'absent' (tile not reported) or 'failed'."""
    if line is None or "error" in line:
        return "failed"
    entry = line.get("tiles", {}).get(str(tile))
    if entry is None:
        return "absent"
    return str(entry.get("state", "absent"))


def removed_outcome(state: str) -> str:
    if state == "missing":
        return "detected"
    if state in ("present", "misplaced"):
        return "called_present"
    return "undetermined"


def fused_line(lines: list[dict[str, Any] | None]) -> dict[str, Any] | None:
    """The fused state after the last of these scans: its line, or the last good line before it."""
    for line in reversed(lines):
        if line is not None and "error" not in line:
            return line
    return None


def visible(scan: dict[str, Any], tile: int) -> bool:
    """Whether the scan could have seen the tile had it been there: >= SEEN_PIXELS of it in a render of
    the expected structure (with the robots and clutter) that give a return for sure (in range, incidence
    below the grazing onset)."""
    counts = scan.get("expected_tile_returnable", scan.get("expected_tile_pixels", {}))
    return int(counts.get(str(tile), 0)) >= SEEN_PIXELS


def shows_s_a(scan: dict[str, Any]) -> bool:
    """Whether the scan's truth has enough returns on the structure's tiles to align on."""
    return sum(scan.get("tile_returns", {}).values()) >= SA_SHOWN_RETURNS


def type_key(truth: dict[str, Any], tile: int) -> str:
    name = truth["tile_types"][str(tile)]
    size = truth.get("type_sizes_cm", {}).get(name)
    if size:
        return f"{name} {'x'.join(f'{v:g}' for v in size)} cm"
    return name


class Tally:
    """Nested counters: counts[scope][set][type][counter]."""

    def __init__(self) -> None:
        self.counts: dict[str, dict[str, dict[str, dict[str, int]]]] = defaultdict(
            lambda: defaultdict(lambda: defaultdict(lambda: defaultdict(int)))
        )

    def add(self, scope: str, set_name: str, tkey: str, counter: str, value: int = 1) -> None:
        for s in dict.fromkeys((set_name, ALL)):
            for t in dict.fromkeys((tkey, ALL)):
                self.counts[scope][s][t][counter] += value

    def get(self, scope: str, set_name: str, tkey: str, counter: str) -> int:
        return self.counts.get(scope, {}).get(set_name, {}).get(tkey, {}).get(counter, 0)

    def plain(self) -> dict[str, Any]:
        return json.loads(json.dumps(self.counts))


@functools.cache
def symmetry_order(structure_file: str, tile: int) -> int:
    """How many turns about the vertical map the tile's planned shape onto itself (the workspace's
    packages are imported here: only scenes with turned tiles need them)."""
    from tiling_assembly.geometry import turn_symmetry
    from tiling_assembly.structure_file import load_structure

    return turn_symmetry(load_structure(structure_file).tiles[tile])


def effective_turn_deg(truth: dict[str, Any], entry: dict[str, Any]) -> float:
    """The turn of a turned tile measured from the nearest turn that maps its shape onto itself
    (the structure file's shape: a square turned 80 degrees is turned 10)."""
    order = symmetry_order(structure_path(truth), entry["id"])
    period = 360.0 / order
    turn = abs(math.degrees(entry["turn"])) % period
    return min(turn, period - turn)


def score_scene(tally: Tally, truth: dict[str, Any], single: list[dict[str, Any] | None],
                fused: list[dict[str, Any] | None], misplaced_rows: list[dict[str, Any]]) -> None:
    set_name = truth["set"]
    scans = truth["scans"][: len(single)]
    last = fused_line(fused)
    for tile in truth["removed"]:
        tk = type_key(truth, tile)
        visible_any = False
        for k, line in enumerate(single):
            outcome = removed_outcome(state_of(line, tile))
            tally.add("single", set_name, tk, "removed")
            tally.add("single", set_name, tk, f"removed_{outcome}")
            if visible(scans[k], tile):
                visible_any = True
                tally.add("single", set_name, tk, "removed_visible")
                tally.add("single", set_name, tk, f"removed_visible_{outcome}")
        outcome = removed_outcome(state_of(last, tile))
        tally.add("fused", set_name, tk, "removed")
        tally.add("fused", set_name, tk, f"removed_{outcome}")
        if visible_any:
            tally.add("fused", set_name, tk, "removed_visible")
            tally.add("fused", set_name, tk, f"removed_visible_{outcome}")
    for tile in truth["present"]:
        tk = type_key(truth, tile)
        for line in single:
            state = state_of(line, tile)
            tally.add("single", set_name, tk, "present")
            tally.add("single", set_name, tk, f"present_{state}")
        state = state_of(last, tile)
        tally.add("fused", set_name, tk, "present")
        tally.add("fused", set_name, tk, f"present_{state}")
    for entry in truth.get("misplaced", []):
        tile, kind = entry["id"], entry["kind"]
        effective = effective_turn_deg(truth, entry) if kind == "turn" else None
        if effective is not None and effective < LEAST_TURN_DEG:
            kind = "turn_onto_symmetry"  # within 15 degrees of a turn that maps the tile onto itself
        tk = type_key(truth, tile)
        states = [state_of(line, tile) for line in single]
        seeing = [k for k in range(len(single)) if scans[k].get("tile_returns", {}).get(str(tile), 0) >= SEEN_PIXELS]
        flagged = any(states[k] == "misplaced" for k in seeing)
        fused_state = state_of(last, tile)
        tally.add("misplaced", set_name, kind, "tiles")
        tally.add("misplaced", set_name, kind, "seen", int(bool(seeing)))
        tally.add("misplaced", set_name, kind, "flagged", int(flagged))
        tally.add("misplaced", set_name, kind, "flagged_any_view", int("misplaced" in states))
        tally.add("misplaced", set_name, kind, "scans", len(states))
        tally.add("misplaced", set_name, kind, "seeing_scans", len(seeing))
        for state in states:
            tally.add("misplaced", set_name, kind, f"scans_{state}")
        for k in seeing:
            tally.add("misplaced", set_name, kind, f"seeing_scans_{states[k]}")
        tally.add("misplaced", set_name, kind, f"fused_{fused_state}")
        misplaced_rows.append({"set": set_name, "bag": truth.get("_bag", ""), "id": tile, "kind": kind,
                               "type": tk, "single": states, "seeing_views": seeing, "fused": fused_state,
                               "effective_turn_deg": effective})
    for line, scan in zip(single, scans, strict=True):
        failed = int(line is None or "error" in line)
        tally.add("scans", set_name, ALL, "single")
        tally.add("scans", set_name, ALL, "single_failed", failed)
        if shows_s_a(scan):
            tally.add("scans", set_name, ALL, "showing")
            tally.add("scans", set_name, ALL, "showing_failed", failed)
    for line in fused:
        tally.add("scans", set_name, ALL, "fused")
        tally.add("scans", set_name, ALL, "fused_failed", int(line is None or "error" in line))


# --- printing ----------------------------------------------------------------------------------

def cell(count: int, total: int) -> str:
    if total == 0:
        return "-"
    return f"{count} ({100.0 * count / total:.0f}%)"


def table(headers: list[str], rows: list[list[str]]) -> str:
    widths = [max(len(str(r[i])) for r in [headers, *rows]) for i in range(len(headers))]
    fmt = lambda r: "  ".join(  # noqa: E731
        str(v).ljust(widths[i]) if i == 0 else str(v).rjust(widths[i]) for i, v in enumerate(r)
    )
    return "\n".join([fmt(headers), fmt(["-" * w for w in widths]), *(fmt(r) for r in rows)])


REMOVED_COLS = ["detected", "undetermined", "called_present"]


def removed_row(t: Tally, scope: str, s: str, tk: str) -> list[str]:
    n = t.get(scope, s, tk, "removed")
    nv = t.get(scope, s, tk, "removed_visible")
    return [str(n), *(cell(t.get(scope, s, tk, f"removed_{c}"), n) for c in REMOVED_COLS),
            str(nv), cell(t.get(scope, s, tk, "removed_visible_detected"), nv)]


def present_row(t: Tally, scope: str, s: str, tk: str) -> list[str]:
    n = t.get(scope, s, tk, "present")
    return [str(n), cell(t.get(scope, s, tk, "present_missing"), n), cell(t.get(scope, s, tk, "present_misplaced"), n)]


def report(t: Tally, sets: list[str], views: int, timings: dict[str, dict[str, list[float]]]) -> str:
    out: list[str] = []
    rows_sets = [*sets, ALL]
    rem_h = ["n", "detected", "undetermined", "called present", "visible", "visible detected"]
    out.append(f"=== Removed tiles (single: each of the first {views} scans on its own, unit tile x scan; "
               f"fused: state after scan {views}, unit tile) ===")
    out.append(table(["set", *(f"single {h}" for h in rem_h)], [[s, *removed_row(t, "single", s, ALL)]
                                                                for s in rows_sets]))
    out.append("")
    out.append(table(["set", *(f"fused {h}" for h in rem_h)], [[s, *removed_row(t, "fused", s, ALL)]
                                                               for s in rows_sets]))
    out.append("")
    out.append("=== Present tiles (at their planned pose) ===")
    hdr = ["set", "single n", "single called missing", "single called misplaced",
           "fused n", "fused called missing", "fused called misplaced"]
    out.append(table(hdr, [[s, *present_row(t, "single", s, ALL), *present_row(t, "fused", s, ALL)]
                           for s in rows_sets]))
    out.append("")
    mis_sets = [s for s in rows_sets if t.get("misplaced", s, ALL, "tiles")]
    if mis_sets:
        out.append(f"=== Misplaced tiles (seen: >= {SEEN_PIXELS} returns on it in a scan; single-view scan counts "
                   "over all scans) ===")
        rows = []
        for s in mis_sets:
            kinds = sorted(k for k in t.counts["misplaced"][s] if k != ALL)
            for kind in [*kinds, ALL]:
                g = lambda c, s=s, kind=kind: t.get("misplaced", s, kind, c)  # noqa: E731
                n, scans = g("tiles"), g("scans")
                rows.append([s, kind, str(n), str(g("seen")), cell(g("flagged"), g("seen")),
                             f"{g('scans_present')}/{scans}", f"{g('scans_missing')}/{scans}",
                             f"{g('scans_misplaced')}/{scans}",
                             cell(g("fused_misplaced"), n), cell(g("fused_present"), n), cell(g("fused_missing"), n)])
        out.append(table(["set", "kind", "tiles", "seen", "flagged in a seeing view", "scans present",
                          "scans missing", "scans misplaced", "fused misplaced", "fused present", "fused missing"],
                         rows))
        out.append("")
    out.append(f"=== Failed scans (error, or no output line); 'S_a shown': >= {SA_SHOWN_RETURNS} returns on "
               "S_a's tiles in the truth ===")
    out.append(table(["set", "single", "fused", "single, of scans showing S_a"],
                     [[s, cell(t.get("scans", s, ALL, "single_failed"), t.get("scans", s, ALL, "single")),
                       cell(t.get("scans", s, ALL, "fused_failed"), t.get("scans", s, ALL, "fused")),
                       cell(t.get("scans", s, ALL, "showing_failed"), t.get("scans", s, ALL, "showing"))]
                      for s in rows_sets]))
    out.append("")
    for s in rows_sets:
        types = sorted(k for k in t.counts["single"].get(s, {}) if k != ALL)
        out.append(f"=== Per tile type: {s} ===")
        hdr = ["tile type", "rem n", "single det", "single undet", "single present",
               "fused n", "fused det", "fused undet", "fused present",
               "pres n", "single missing", "single misplaced", "fused missing", "fused misplaced"]
        rows = []
        for tk in [*types, ALL]:
            sr, fr = removed_row(t, "single", s, tk), removed_row(t, "fused", s, tk)
            sp, fp = present_row(t, "single", s, tk), present_row(t, "fused", s, tk)
            rows.append([tk, *sr[:4], *fr[:4], sp[0], sp[1], sp[2], fp[1], fp[2]])
        out.append(table(hdr, rows))
        out.append("")
    out.append("=== Wall time of the whole classify process (median) ===")
    rows = []
    for s in rows_sets:
        tm = timings.get(s, {})
        rows.append([s, *(f"{statistics.median(tm[k]):.2f} s" if tm.get(k) else "-"
                          for k in ("single_bag", "single_scan", "fused_bag", "fused_scan"))])
    out.append(table(["set", "--no-fuse per bag", "per scan", "fused per bag", "per scan"], rows))
    return "\n".join(out)


# --- main --------------------------------------------------------------------------------------

def main(argv: list[str] | None = None) -> int:
    return run_command(build_parser(), _run, argv)


def _run(args: argparse.Namespace) -> int:
    root = Path(args.scenes)
    if not root.is_dir():
        raise InputError(f"--scenes {root}: not a folder")
    if args.views < 1:
        raise InputError(f"--views must be at least 1, got {args.views}")
    if args.params and not Path(args.params).is_file():
        raise InputError(f"--params {args.params}: no such file")
    wanted = None if args.sets == "all" else {s.strip() for s in args.sets.split(",") if s.strip()}
    scenes = find_scenes(root, wanted)
    if not scenes:
        raise InputError(f"no scenes (folders with truth.json) under {root}")
    ros2 = shlex.split(args.ros2)
    if args.params:
        args.params = str(Path(args.params).resolve())
    tally = Tally()
    misplaced_rows: list[dict[str, Any]] = []
    timings: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    sets: list[str] = []
    per_bag: list[dict[str, Any]] = []
    start = time.monotonic()
    for i, (folder, truth) in enumerate(scenes, 1):
        set_name = truth["set"]
        if set_name not in sets:
            sets.append(set_name)
        truth["_bag"] = str(folder)
        runs = {}
        for mode, fuse in (("single", False), ("fused", True)):
            command = classify_command(ros2, folder, truth, args, fuse)
            lines, stderr, code, wall = run_classify(command, args.timeout)
            if code != 0:
                tail = (stderr.strip().splitlines() or ["(no output)"])[-1]
                print(f"  {folder}: classify ({mode}) exit {code}: {tail}", file=sys.stderr)
            runs[mode] = per_scan(lines, truth, args.views)
            n_scans = max(1, len(truth["scans"]))
            for s in (set_name, ALL):
                timings[s][f"{mode}_bag"].append(wall)
                timings[s][f"{mode}_scan"].append(wall / n_scans)
            runs[f"{mode}_meta"] = {"exit": code, "wall": round(wall, 3), "command": command}
        score_scene(tally, truth, runs["single"], runs["fused"], misplaced_rows)
        per_bag.append({
            "bag": str(folder), "set": set_name, "removed": truth["removed"],
            "misplaced": [m["id"] for m in truth.get("misplaced", [])],
            "single": [{str(tile): state_of(line, tile) for tile in truth["expected"]} for line in runs["single"]],
            "fused": [{str(tile): state_of(line, tile) for tile in truth["expected"]} for line in runs["fused"]],
            "errors": [line.get("error") if line else "no output" for line in runs["single"]],
            "wall_single": runs["single_meta"]["wall"], "wall_fused": runs["fused_meta"]["wall"],
        })
        print(f"[{i}/{len(scenes)}] {folder.relative_to(root)}: single {runs['single_meta']['wall']:.1f} s, "
              f"fused {runs['fused_meta']['wall']:.1f} s", file=sys.stderr, flush=True)
    order = [s for s in ("high_clean", "high_world", "low_world", "low_close", "robots_near_camera", "misplaced",
                         "misplaced_low") if s in sets] + sorted(s for s in sets if s not in {
        "high_clean", "high_world", "low_world", "low_close", "robots_near_camera", "misplaced", "misplaced_low"})
    text = report(tally, order, args.views, timings)
    print(text)
    print(f"\n{len(scenes)} bags scored in {time.monotonic() - start:.0f} s")
    if args.json:
        data = {
            "scenes": str(root), "views": args.views, "params": args.params, "classify_args": args.classify_arg,
            "ros2": ros2, "seen_pixels": SEEN_PIXELS, "counts": tally.plain(),
            "timing_median_s": {s: {k: statistics.median(v) for k, v in tm.items() if v} for s, tm in timings.items()},
            "misplaced_tiles": misplaced_rows, "bags": per_bag,
        }
        Path(args.json).write_text(json.dumps(data, indent=1) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
