"""The experiment's report: the paper's tables and figures from our trials (paper section 3.2).

Text for the terminal (Table 1, Table 2, detection statistics beside the paper's, completion and
makespans) and a report folder: `report.md` with pictures of the structure coloured by tile state
at the end of a trial and of each robot's schedule over time (Gantt chart with waits, auctions and
re-placements marked).
"""

from __future__ import annotations

import json
import math
import re
import statistics
from collections import Counter
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import Patch
from mpl_toolkits.mplot3d.art3d import Poly3DCollection

from tiling_assembly.structure import Structure
from tiling_sim.experiment_result import ExperimentConfig, ExperimentResult
from tiling_sim.plan_vs_execution import account_lines, planned_completion, robot_accounts
from tiling_sim.trial_record import (
    MISSING,
    OCCLUDED,
    PRESENT,
    PlanRecord,
    TrialRecord,
    allocation_rows,
    detection_stats,
    duplicate_placements,
    false_missing_calls,
    false_repairs,
    lost_placements,
    misplacement_outcomes,
    removal_outcomes,
    schedule,
    total_stats,
)

STATE_COLOURS = {PRESENT: "#3a9d3a", MISSING: "#d43a3a", OCCLUDED: "#e8c23a", "unknown": "#9a9a9a"}
KIND_COLOURS = {"place": "#4a78c2", "replace": "#e0892b", "take off": "#2f9e6e", "failed": "#c23a3a",
                "wait": "#d9d9d9", "wait for room": "#8c6bb1"}
PAPER = {"removed": 22, "detected": 12, "undetermined": 10, "missing_called_present": 0, "present_called_missing": 1}


def _pretty(type_name: str) -> str:
    return type_name.replace("_", " ").title()


def _table(headers: list[str], rows: list[list[str]]) -> list[str]:
    widths = [max(len(h), *(len(r[k]) for r in rows)) if rows else len(h) for k, h in enumerate(headers)]
    line = "  ".join(h.ljust(w) for h, w in zip(headers, widths, strict=True))
    out = [line, "  ".join("-" * w for w in widths)]
    out += ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    return out


def header(config: ExperimentConfig, structure: Structure) -> str:
    return (
        f"Experiment: {structure.name} ({len(structure)} tiles, {len(structure.tile_types)} types), "
        f"{config.robots} assembly robots + {config.vi_robots} VI robot{'s' if config.vi_robots > 1 else ''}, "
        f"{config.trials} trials with {config.removals} "
        f"tiles removed in all, seed {config.seed}, simulated time at {config.real_time_factor:g}x"
    )


def table1(structure: Structure, tasks: dict[str, list[int]]) -> list[str]:
    robots = list(tasks)
    rows = []
    for k in range(max((len(t) for t in tasks.values()), default=0)):
        row = []
        for robot in robots:
            tiles = tasks[robot]
            row += [_pretty(structure.tiles[tiles[k]].type_name), str(tiles[k])] if k < len(tiles) else ["", ""]
        rows.append(row)
    headers = [h for r in robots for h in (r.replace("robot", "Robot "), "Tile ID")]
    return _table(headers, rows)


def table2(record: TrialRecord, robots: list[str]) -> list[str]:
    rows = allocation_rows(record, robots)
    headers = ["t (s)", *[r.replace("robot", "Robot ") for r in robots]]
    return _table(headers, [[row["t"], *[row[r] for r in robots]] for row in rows])


def detection_table(result: ExperimentResult) -> list[str]:
    stats = total_stats(result.fault_trials())
    rate = stats.present_judged_missing / stats.present_judgements if stats.present_judgements else 0.0
    rows = [
        ["removed tiles", str(stats.removed), str(PAPER["removed"])],
        ["inspection's last word on a removed tile:", "", ""],
        ["  missing (detected)", str(stats.reported_missing), str(PAPER["detected"])],
        ["  undetermined", str(stats.reported_nothing), str(PAPER["undetermined"])],
        ["  present or misplaced (false positives)", str(stats.left_present), str(PAPER["missing_called_present"])],
        ["false negatives: auction for a present tile", str(stats.present_called_missing),
         str(PAPER["present_called_missing"])],
        ["  (beyond the paper) for a tile lying wrong", str(stats.wrong_called_missing), "-"],
        ["who found a removed tile first (beyond the paper):", "", ""],
        ["  inspection (its call opened the auction)", str(stats.detected), "-"],
        ["  a robot placing a tile on it", str(stats.found_by_robot), "-"],
        ["  nobody", str(stats.undetermined), "-"],
        ["stricter than the paper:", "", ""],
        ["  removed tiles some scan called present", str(stats.missing_called_present), "-"],
        ["  present tiles some scan called missing", str(stats.present_tiles_called_missing), "-"],
        ["  present tiles judged missing, per scan", f"{rate:.2%}", "-"],
    ]
    if stats.detection_delays:
        delay = statistics.median(stats.detection_delays)
        rows.append(["median removal -> first finding (simulated s)", f"{delay:.1f}", "-"])
    rows.append(["per type: removed / inspection said missing / found", "", ""])
    for type_name, (removed, reported, found) in sorted(stats.by_type.items()):
        rows.append([f"  {_pretty(type_name)}", f"{removed} / {reported} / {found}", "-"])
    return _table(["", "this run", "paper"], rows)


def misplacement_table(result: ExperimentResult) -> list[str]:
    """Placements that landed wrong, per kind: injected, detected (repair auctioned), repaired; false
    repairs; the time from landing to the right tile in place."""
    outcomes = [o for r in result.fault_trials() for o in misplacement_outcomes(r)]
    rows = []
    for kind in ("shift", "turn", "wrong_type"):
        mine = [o for o in outcomes if o.kind == kind]
        detected = sum(o.detected_at is not None for o in mine)
        repaired = sum(o.repaired_at is not None for o in mine)
        rows.append([kind.replace("_", " "), str(len(mine)), str(detected), str(repaired)])
    rows.append(["all", str(len(outcomes)), str(sum(o.detected_at is not None for o in outcomes)),
                 str(sum(o.repaired_at is not None for o in outcomes))])
    lines = _table(["landed wrong", "injected", "detected", "repaired"], rows)
    times = [o.repaired_at - o.injected_at for o in outcomes if o.repaired_at is not None]
    wrongly = sum(len(false_repairs(r)) for r in result.fault_trials())
    median = f"{statistics.median(times):.0f} s simulated" if times else "-"
    asked = sum(r.wrong_landings_planned for r in result.fault_trials())
    by_scans = sum(o.found_by == "inspection" for o in outcomes)
    by_robots = sum(o.found_by == "robot" for o in outcomes)
    removed = sum(o.removed_at is not None and o.detected_at is None for o in outcomes)
    taken_away = (f"; {removed} taken away by a removal fault before any repair (then a missing tile)"
                  if removed else "")
    return [*lines, f"asked for {asked}, {len(outcomes)} landed wrong (the others had no room to and landed "
                    f"as planned); found by inspection {by_scans}, by a robot in its way {by_robots}{taken_away}",
            f"false repairs (repair auctioned for a tile lying right): {wrongly}; "
            f"median landing -> right tile in place: {median}"]


def first_plan(result: ExperimentResult) -> PlanRecord | None:
    """The plan the trials started from (revision 0; every trial starts from the same)."""
    return next((p for r in result.records for p in r.plans if p.revision == 0), None)


def makespan_lines(result: ExperimentResult) -> list[str]:
    lines = []
    baseline = [r.makespan() for r in result.records if r.trial == 0 and r.complete()]
    faulty = [r.makespan() for r in result.fault_trials() if r.complete()]
    first = first_plan(result)
    if first is not None:
        lines.append(f"Planned makespan {first.makespan:.0f} s (lower bound {first.lower_bound:.0f} s)")
    if baseline:
        lines.append(f"Makespan without faults: {baseline[0]:.0f} s simulated")
        trial0 = next(r for r in result.records if r.trial == 0)
        model = result.time_model()
        completion = None if first is None else planned_completion(first, result.structure, model)
        lines += account_lines(robot_accounts(trial0, result.structure, model, result.robot_starts),
                               None if first is None else first.makespan, baseline[0], completion)
    if faulty:
        lines.append(
            f"Makespan with faults: median {statistics.median(faulty):.0f} s, "
            f"range {min(faulty):.0f}-{max(faulty):.0f} s over {len(faulty)} trials"
        )
    lines += room_wait_lines(result)
    verdicts = [v for r in result.records for v in r.verdicts]
    if verdicts:
        failed = sum(1 for v in verdicts if v.problem)
        unseen = sum(1 for v in verdicts if "S_a not in view" in v.problem)
        seen = len(verdicts) - unseen
        delay_ms = statistics.median(v.wall_delay for v in verdicts) * 1000
        lines.append(
            f"Scans: {len(verdicts)} judged, {failed} ({100.0 * failed / len(verdicts):.1f}%) gave no states; "
            f"scan -> tile states (wall clock): median {delay_ms:.0f} ms"
        )
        lines.append(
            f"  S_a not in view (hidden by robots or out of the image): {unseen}; of the {seen} scans that saw it, "
            f"{failed - unseen} ({100.0 * (failed - unseen) / max(1, seen):.1f}%) failed to align"
        )
        kinds = Counter(re.sub(r"[-+]?\d+(\.\d+)?", "N", v.problem) for v in verdicts if v.problem)
        lines.extend(f"  no states: {count} x {kind}" for kind, count in kinds.most_common(4))
        unjudged = sum(len(r.unjudged_scans) for r in result.records)
        if unjudged:
            lines.append(f"  {unjudged} more scans got no answer from vi_node in time")
    latencies = [x for r in result.records for x in r.award_latencies]
    if latencies:
        lines.append(
            f"Missing tile detected -> award received by the winner (wall clock, over DDS): median "
            f"{percentile(latencies, 50) * 1000:.1f} ms, p95 {percentile(latencies, 95) * 1000:.1f} ms, "
            f"max {max(latencies) * 1000:.1f} ms over {len(latencies)} awards"
        )
    copies: Counter[str] = Counter()
    for record in result.records:
        copies.update(record.copies)
    if copies:
        lines.append("Auction messages sent again (unanswered over the link): "
                     + ", ".join(f"{n} {topic}" for topic, n in sorted(copies.items())))
    lines += network_lines(result)
    duplicates = sum(len(duplicate_placements(r)) for r in result.records)
    lost = sum(len(lost_placements(r)) for r in result.records)
    lines.append(f"Tiles placed twice (or carried to a place already taken): {duplicates}; "
                 f"tiles not in place when an unfinished trial ended: {lost}")
    return lines


def network_lines(result: ExperimentResult) -> list[str]:
    settings = result.config.network
    if not settings.separate_hosts:
        return []
    rate = f"{settings.rate_mbit:g} Mbit/s" if settings.rate_mbit is not None else "no rate limit"
    outages = ", ".join(f"{o.host} at {o.at:g} s for {o.duration:g} s" for o in settings.outages) or "none"
    lines = [f"Network: a host per computer; robots' links {settings.loss_percent:g}% loss, {rate}, "
             f"{settings.delay_ms:g} ms delay; outages: {outages}; {result.config.real_time_factor:g}x real time"]
    for robot, c in sorted(result.link_counters.items()):
        lines.append(f"  {robot}'s link: {c['sent_packets']} frames sent, {c['received_packets']} received, "
                     f"{c['lost_sent'] + c['lost_received']} lost at random, {c['outage_dropped']} in outages, "
                     f"{c['queue_dropped']} by the rate limit")
    return lines


def percentile(values: list[float], q: float) -> float | None:
    """The q-th percentile (nearest rank), None without values."""
    if not values:
        return None
    ranked = sorted(values)
    return ranked[max(0, math.ceil(q / 100 * len(ranked)) - 1)]


def chosen_trial(result: ExperimentResult) -> TrialRecord | None:
    """The trial shown in Table 2 and the pictures: the first with a detection, else the first."""
    detected = [r for r in result.fault_trials() if r.announcements]
    return detected[0] if detected else (result.records[0] if result.records else None)


def room_wait_lines(result: ExperimentResult) -> list[str]:
    """What robots standing where another needed to be cost (`standing_room`), per trial."""
    lines = []
    for record in result.records:
        waits = record.room_waits
        if not waits:
            continue
        makespan = record.makespan()
        share = f" ({100.0 * sum(w.seconds for w in waits) / makespan:.1f}% of the makespan, summed over robots)" \
            if makespan else ""
        forced = sum(1 for w in waits if w.forced)
        waited = [w for w in waits if w.seconds > 0]
        lines.append(f"Trial {record.trial}: another robot stood where a robot needed to be {len(waits)} times: "
                     f"it stopped elsewhere {sum(1 for w in waits if w.elsewhere)} times, waited {len(waited)} times, "
                     f"{sum(w.seconds for w in waits):.0f} s in all{share}"
                     + (f"; {forced} went in anyway after waiting their patience" if forced else ""))
    return lines


def summary_text(result: ExperimentResult) -> str:
    robots = result.config.robot_names
    lines = [""]
    first_plan = next((p for r in result.records for p in r.plans if p.revision == 0), None)
    if first_plan is not None:
        title = f"Table 1. Initial allocation ({first_plan.method} planner)"
        lines += [title, *table1(result.structure, first_plan.tasks), ""]
    trial = chosen_trial(result)
    if trial is not None:
        title = f"Table 2. Allocation after detection of missing tiles (trial {trial.trial})"
        lines += [title, *table2(trial, robots), ""]
    lines += ["Detection statistics over the trials with faults", *detection_table(result), ""]
    if any(e.kind == "misplaced" for r in result.fault_trials() for e in r.events):
        lines += ["Placements that landed wrong, and their repair", *misplacement_table(result), ""]
    if result.interrupted:
        lines.append(f"Interrupted: only the {len(result.records)} trial(s) finished before are reported")
    finished = [r for r in result.fault_trials() if r.complete()]
    verdict = "yes" if len(finished) == len(result.fault_trials()) else "NO"
    total = len(result.fault_trials())
    lines.append(f"Every trial finished the structure correctly: {verdict} ({len(finished)}/{total})")
    for record in result.records:
        if not record.complete():
            lines.append(f"  trial {record.trial}: {record.failure or 'did not finish in time'}")
    unclean = [f"trial {r.trial} {name} ({code})" for r in result.records for name, code in r.unclean_exits.items()]
    lines.append(f"Nodes that did not stop cleanly at the end of a trial (exit code): {', '.join(unclean) or 'none'}")
    lines += makespan_lines(result)
    return "\n".join(lines)


def draw_structure(structure: Structure, record: TrialRecord, path: Path) -> None:
    """The structure coloured by the last state the inspection gave each tile."""
    fig = plt.figure(figsize=(7, 5))
    ax = fig.add_subplot(projection="3d")
    for tile_id, tile in structure.tiles.items():
        state = record.final_states.get(tile_id, "unknown")
        faces = [tile.face_corners(k) for k in range(len(tile.shape.faces))]
        ax.add_collection3d(Poly3DCollection(faces, facecolor=STATE_COLOURS.get(state, "#9a9a9a"),
                                             edgecolor="#222222", linewidths=0.5, alpha=0.9))
        centre = tile.centroid
        ax.text(centre[0], centre[1], tile.aabb[1][2] + 0.005, str(tile_id), fontsize=7, ha="center")
    lo, hi = structure.bounds
    margin = 0.1 * max(hi[:2] - lo[:2])
    ax.set_xlim(lo[0] - margin, hi[0] + margin)
    ax.set_ylim(lo[1] - margin, hi[1] + margin)
    ax.set_zlim(0, hi[2] + margin)
    ax.set_box_aspect((hi[0] - lo[0] + 2 * margin, hi[1] - lo[1] + 2 * margin, hi[2] + margin))
    ax.view_init(elev=35, azim=-60)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{structure.name}, trial {record.trial}: tile states at the end")
    ax.legend(handles=[Patch(color=c, label=s) for s, c in STATE_COLOURS.items()], loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def draw_gantt(record: TrialRecord, robots: list[str], path: Path) -> None:
    """Each robot's schedule: placements, re-placements, failed attempts, waits; removals and awards."""
    fig, ax = plt.subplots(figsize=(10, 1.2 + 0.8 * len(robots)))
    rows = {robot: k for k, robot in enumerate(robots)}
    for interval in schedule(record):
        if interval.robot not in rows:
            continue
        y = rows[interval.robot]
        height = 0.35 if interval.kind.startswith("wait") else 0.7
        ax.broken_barh([(interval.start, interval.end - interval.start)], (y - height / 2, height),
                       facecolors=KIND_COLOURS[interval.kind], edgecolor="#333333", linewidth=0.4)
        if interval.tile and interval.end - interval.start > 4:
            ax.text((interval.start + interval.end) / 2, y, str(interval.tile), ha="center", va="center", fontsize=7)
    for event in record.removals():
        ax.axvline(event.t, color="#c23a3a", linestyle="--", linewidth=0.8)
        ax.text(event.t + 1.0, len(robots) - 0.25, f"tile {event.tile} removed", fontsize=6,
                color="#c23a3a", va="top", ha="left")
    for event in (e for e in record.events if e.kind == "misplaced"):
        ax.axvline(event.t, color="#2f9e6e", linestyle=":", linewidth=0.8)
        ax.text(event.t + 1.0, len(robots) - 0.45, f"tile {event.tile} landed wrong ({event.misplacement})",
                fontsize=6, color="#2f9e6e", va="top", ha="left")
    for award in record.awards:
        if award.winner in rows:
            ax.plot(award.t, rows[award.winner] + 0.45, marker="v", color="#7b3fb3", markersize=7)
    ax.set_yticks(range(len(robots)), [r.replace("robot", "Robot ") for r in robots])
    ax.set_xlabel("simulated time (s)")
    ax.set_ylim(-0.7, len(robots) - 0.2)
    ax.set_title(f"Trial {record.trial}: schedule per robot (triangles: auctions won)")
    ax.legend(handles=[Patch(color=c, label=k) for k, c in KIND_COLOURS.items()], loc="lower right", fontsize=7,
              ncol=4)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def write(result: ExperimentResult) -> Path:
    folder = result.config.report_dir
    folder.mkdir(parents=True, exist_ok=True)
    robots = result.config.robot_names
    trial = chosen_trial(result)
    lines = [f"# {header(result.config, result.structure)}", "", "```", summary_text(result).strip(), "```", ""]
    if trial is not None:
        draw_structure(result.structure, trial, folder / f"structure_trial_{trial.trial:02d}.png")
        draw_gantt(trial, robots, folder / f"gantt_trial_{trial.trial:02d}.png")
        lines += [f"## Trial {trial.trial}", "",
                  f"![structure coloured by tile state](structure_trial_{trial.trial:02d}.png)", "",
                  f"![schedule per robot](gantt_trial_{trial.trial:02d}.png)", ""]
    baseline = next((r for r in result.records if r.trial == 0 and r.complete()), None)
    if baseline is not None and baseline is not trial:
        draw_gantt(baseline, robots, folder / "gantt_trial_00.png")
        lines += ["## Trial 0 (no faults)", "", "![schedule without faults](gantt_trial_00.png)", ""]
    lines += ["## Trials", "",
              "| trial | seed | removed | inspection said missing | found first by inspection | auctions "
              "| makespan (s) | result |",
              "|---|---|---|---|---|---|---|---|"]
    for record in result.records:
        stats = detection_stats(record)
        makespan = f"{record.makespan():.0f}" if record.makespan() is not None else "-"
        outcome = "complete" if record.complete() else (record.failure or "timed out")
        lines.append(f"| {record.trial} | {record.seed} | {stats.removed} | {stats.reported_missing} "
                     f"| {stats.detected} | {len(record.awards)} | {makespan} | {outcome} |")
    lines += ["", "## Decisions of the auction node, trial by trial", ""]
    for record in result.records:
        if record.decisions:
            lines += [f"Trial {record.trial}:", "", *[f"- {d}" for d in record.decisions], ""]
    path = folder / "report.md"
    path.write_text("\n".join(lines) + "\n")
    (folder / "results.json").write_text(json.dumps(results_json(result), indent=1) + "\n")
    return path


def results_json(result: ExperimentResult) -> dict[str, object]:
    """The figures of every trial, for scripts and tests."""
    trials = []
    for record in result.records:
        stats = detection_stats(record)
        trials.append({
            "trial": record.trial, "seed": record.seed, "complete": record.complete(),
            "failure": record.failure, "timed_out": record.timed_out, "makespan": record.makespan(),
            "unclean_exits": record.unclean_exits,
            "removed": stats.removed, "reported_missing": stats.reported_missing,
            "reported_nothing": stats.reported_nothing, "left_present": stats.left_present,
            "detected": stats.detected, "found_by_robot": stats.found_by_robot,
            "undetermined": stats.undetermined,
            "present_tiles_called_missing": stats.present_tiles_called_missing,
            "missing_called_present": stats.missing_called_present,
            "present_called_missing": stats.present_called_missing,
            "wrong_called_missing": stats.wrong_called_missing,
            "auctions": len(record.awards), "award_latencies": record.award_latencies,
            "award_latency_p50": percentile(record.award_latencies, 50),
            "award_latency_p95": percentile(record.award_latencies, 95),
            "messages_resent": record.copies,
            "duplicate_placements": duplicate_placements(record), "lost_placements": lost_placements(record),
            "link_changes": [{"t": round(c.t, 2), "robot": c.host, "up": c.up} for c in record.link_changes],
            "scans_judged": len(record.verdicts), "scans_without_states": sum(1 for v in record.verdicts if v.problem),
            "scans_judged_by": dict(Counter(v.robot for v in record.verdicts)),
            "room_waits": [w.as_dict() for w in record.room_waits],
            "scans_not_in_view": sum(1 for v in record.verdicts if "S_a not in view" in v.problem),
            "scan_verdict_delays": [round(v.wall_delay, 4) for v in record.verdicts],
            "scan_problems": [v.problem for v in record.verdicts if v.problem],
            "scans_unanswered": len(record.unjudged_scans),
            "plans": [{"revision": p.revision, "tasks": p.tasks} for p in record.plans],
            "placements": [{"t": e.t, "tile": e.tile, "robot": e.robot} for e in record.events if e.kind == "placed"],
            "removals": [
                {"t": o.removed_at, "tile": o.tile, "detected_at": o.detected_at,
                 "found_by_robot_at": o.found_by_robot_at, "back_at": o.back_at,
                 "scans_calling_it_present": o.called_present, "last_judged": o.last_judged}
                for o in removal_outcomes(record)
            ],
            "false_missing_calls": false_missing_calls(record),
            "wrong_tiles_called_missing": false_missing_calls(record, lying_wrong=True),
            "wrong_landings_asked": record.wrong_landings_planned,
            "misplacements": [o.as_dict() for o in misplacement_outcomes(record)],
            "false_repairs": len(false_repairs(record)),
            "robot_accounts": [a.as_dict() for a in robot_accounts(record, result.structure, result.time_model(),
                                                                    result.robot_starts)],
            "decisions": record.decisions,
        })
    first = first_plan(result)
    return {"structure": result.structure.name, "robots": result.config.robot_names,
            "vi_robots": result.config.vi_robot_names if result.config.inspection else [],
            "planned_makespan": None if first is None else first.makespan,
            "planned_completion": None if first is None else planned_completion(first, result.structure,
                                                                                result.time_model()),
            "lower_bound": None if first is None else first.lower_bound,
            "network": {**result.config.network.as_dict(), "real_time_factor": result.config.real_time_factor,
                        "link_counters": result.link_counters},
            "interrupted": result.interrupted, "trials": trials}
