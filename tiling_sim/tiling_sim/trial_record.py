"""What happened in one simulated trial, and the figures the paper reports (section 3.2).

The record holds the world's truth (tiles placed and removed, with simulated times), every scan's
judgement of every tile, the auctions and the robots' progress; the functions below turn it into
the paper's detection statistics, the allocation after detections (Table 2), a schedule per robot
for the Gantt chart, and makespans.

The paper counts what its scanning robot finally reported of each removed tile: "detected" (missing),
"undetermined", or present (a "false positive"); and present tiles it reported missing ("false
negatives"). Here the inspection's last word on a removed tile is the last verdict of a scan that saw
it, before anyone found it missing or it was put back; a removed tile reported misplaced counts as a
false positive too (the inspection claimed it was there). Beyond the paper: who found each removed
tile first (inspection, whose call opened the auction, or a robot placing a tile on it), and stricter
counts (removed tiles any single scan called present, present tiles any single scan called missing).

Beyond the paper (its future work): placements that landed wrong (shifted, turned, a tile of the
wrong type), when a repair of each was auctioned (its detection: two scans, or a robot that found it
in the way) and when the right tile was in place again; and repairs auctioned for tiles that lay
right ("false repairs").
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

PRESENT, MISSING, OCCLUDED, MISPLACED = "present", "missing", "occluded", "misplaced"
REASON_MISSING = 0  # AuctionAnnouncement reasons: found missing by inspection
REASON_FOUND_MISSING = 3  # found missing by a robot placing a tile on it
REASON_MISPLACED = 4  # a repair: the tile lies wrong
GONE = ("removed", "taken_off")  # events that end a tile's stay on the structure


@dataclass(frozen=True)
class WorldEvent:
    t: float  # s of simulated time
    kind: str  # place_started, placed, misplaced, refused, dropped, removed, removal_started, taken_off, complete
    tile: int = 0
    robot: str = ""
    reason: str = ""
    misplacement: str = ""  # misplaced: shift, turn or wrong_type


@dataclass(frozen=True)
class Scan:
    t: float
    states: dict[int, str]  # tile id -> present / missing / occluded / misplaced
    fresh: frozenset[int] = frozenset()  # tiles this scan saw (fused states repeat older views)


@dataclass(frozen=True)
class Verdict:
    """The inspection's answer to one simulated scan: how long it took, and why it had no states."""

    t: float  # s of simulated time of the scan
    wall_delay: float  # s of wall time from the scan's publication to its verdict on /tile_states
    problem: str = ""  # empty: classified
    robot: str = ""  # the VI robot that took it


@dataclass(frozen=True)
class RoomWait:
    """An assembly robot found another robot where it needed to stand (`standing_room`): it waited for
    it to leave, or stopped elsewhere."""

    robot: str
    since: float  # s of simulated time
    seconds: float
    in_the_way: tuple[str, ...]
    forced: bool  # it went there after all, the other robot still in the way
    elsewhere: bool = False  # it stopped at another spot (beside a cache, round a tile)

    def as_dict(self) -> dict[str, object]:
        return {"robot": self.robot, "since": self.since, "seconds": self.seconds,
                "in_the_way": list(self.in_the_way), "forced": self.forced, "elsewhere": self.elsewhere}


@dataclass(frozen=True)
class Announcement:
    t: float
    auction_id: int
    tile: int
    reason: int


@dataclass(frozen=True)
class AwardRecord:
    t: float
    auction_id: int
    tile: int
    winner: str
    decision: str


@dataclass(frozen=True)
class StatusSample:
    t: float
    robot: str
    state: int  # RobotStatus constant
    current_tile: int


@dataclass(frozen=True)
class PlanRecord:
    t: float
    revision: int
    method: str
    tasks: dict[str, list[int]]
    makespan: float
    lower_bound: float
    finishes: dict[str, float] = field(default_factory=dict)  # s, each robot back at a cache after its last tile


@dataclass
class TrialRecord:
    trial: int
    seed: int
    removals_planned: int
    wrong_landings_planned: int = 0  # tiles asked to land shifted, turned or of the wrong type
    tile_types: dict[int, str] = field(default_factory=dict)
    plans: list[PlanRecord] = field(default_factory=list)
    events: list[WorldEvent] = field(default_factory=list)
    scans: list[Scan] = field(default_factory=list)
    verdicts: list[Verdict] = field(default_factory=list)
    unjudged_scans: list[float] = field(default_factory=list)  # s of simulated time of scans never answered
    room_waits: list[RoomWait] = field(default_factory=list)
    announcements: list[Announcement] = field(default_factory=list)
    awards: list[AwardRecord] = field(default_factory=list)
    award_latencies: list[float] = field(default_factory=list)  # s of wall time
    statuses: list[StatusSample] = field(default_factory=list)
    decisions: list[str] = field(default_factory=list)
    started_at: float = 0.0  # s of simulated time the build started
    completed_at: float | None = None
    timed_out: bool = False
    failure: str = ""
    unclean_exits: dict[str, int] = field(default_factory=dict)  # node -> exit code when stopped
    final_states: dict[int, str] = field(default_factory=dict)
    copies: dict[str, int] = field(default_factory=dict)  # topic -> messages heard again (re-sent)
    link_changes: list = field(default_factory=list)  # team_network.LinkChange: outages applied

    # --- truth -------------------------------------------------------------------------------
    def presence_intervals(self) -> dict[int, list[tuple[float, float]]]:
        """Per tile, the simulated-time intervals it was physically in place."""
        intervals: dict[int, list[tuple[float, float]]] = {}
        since: dict[int, float] = {}
        for event in sorted(self.events, key=lambda e: e.t):
            if event.kind == "placed":
                since[event.tile] = event.t
            elif event.kind in GONE and event.tile in since:
                intervals.setdefault(event.tile, []).append((since.pop(event.tile), event.t))
        for tile, start in since.items():
            intervals.setdefault(tile, []).append((start, float("inf")))
        return intervals

    def present_at(self, tile: int, t: float, intervals: dict[int, list[tuple[float, float]]]) -> bool:
        return any(a <= t < b for a, b in intervals.get(tile, []))

    def lying_wrong_at(self, tile: int, t: float, stays: list[tuple[WorldEvent, float]]) -> bool:
        """Whether `tile` lay shifted, turned or of the wrong type at `t` (of `wrong_stays`)."""
        return any(landing.tile == tile and landing.t <= t < gone for landing, gone in stays)

    def removals(self) -> list[WorldEvent]:
        return [e for e in self.events if e.kind == "removed"]

    def complete(self) -> bool:
        return self.completed_at is not None and not self.timed_out and not self.failure

    def makespan(self) -> float | None:
        return None if self.completed_at is None else self.completed_at - self.started_at


@dataclass(frozen=True)
class MisplacementOutcome:
    tile: int
    kind: str  # shift, turn, wrong_type
    injected_at: float  # s of simulated time it landed wrong
    detected_at: float | None  # its repair was auctioned
    taken_off_at: float | None
    repaired_at: float | None  # the right tile was in place
    found_by: str | None = None  # "inspection" (two scans) or "robot" (found it in its way)
    removed_at: float | None = None  # a removal fault took the wrong tile away before a repair did

    def as_dict(self) -> dict[str, object]:
        return {"tile": self.tile, "kind": self.kind, "injected_at": self.injected_at,
                "detected_at": self.detected_at, "repaired_at": self.repaired_at, "found_by": self.found_by,
                "removed_at": self.removed_at}


def wrong_stays(record: TrialRecord) -> list[tuple[WorldEvent, float]]:
    """Each placement that landed wrong, with the time it left the structure (inf: never)."""
    events = sorted(record.events, key=lambda e: e.t)
    stays = []
    for landing in (e for e in events if e.kind == "misplaced"):
        gone = next((e.t for e in events if e.kind in GONE and e.tile == landing.tile and e.t >= landing.t), None)
        stays.append((landing, float("inf") if gone is None else gone))
    return stays


def misplacement_outcomes(record: TrialRecord) -> list[MisplacementOutcome]:
    wrong_landings = {(e.tile, e.t) for e in record.events if e.kind == "misplaced"}
    outcomes = []
    for landing, gone in wrong_stays(record):
        detected = _first_announcement(record, landing.tile, REASON_MISPLACED, landing.t, gone)
        right = next((e.t for e in sorted(record.events, key=lambda e: e.t)
                      if e.kind == "placed" and e.tile == landing.tile and e.t >= gone
                      and (e.tile, e.t) not in wrong_landings), None)
        removed = next((e.t for e in record.events if e.kind == "removed" and e.tile == landing.tile
                        and e.t == gone), None)
        outcomes.append(MisplacementOutcome(landing.tile, landing.misplacement, landing.t, detected,
                                            None if gone == float("inf") else gone, right,
                                            _repair_finder(record, landing.tile, detected), removed))
    return outcomes


def _repair_finder(record: TrialRecord, tile: int, detected: float | None) -> str | None:
    """Who found the wrong tile whose repair was auctioned at `detected`: the auction node's decision
    line that opened it says (the k-th repair of a tile has its k-th "lies wrong" line)."""
    if detected is None:
        return None
    repairs = [a.t for a in record.announcements if a.tile == tile and a.reason == REASON_MISPLACED]
    lines = [d for d in record.decisions if d.startswith(f"tile {tile} lies wrong (")]
    k = repairs.index(detected)
    if k >= len(lines):
        return None
    return "inspection" if lines[k].startswith(f"tile {tile} lies wrong (scans") else "robot"


def false_repairs(record: TrialRecord) -> list[dict[str, float]]:
    """Repairs auctioned for tiles that were in place and lay right: when, which tile. (A repair of a
    tile that is not there at all puts it back, as a re-placement would: not counted here.)"""
    stays = wrong_stays(record)
    intervals = record.presence_intervals()
    return [{"t": a.t, "tile": a.tile} for a in record.announcements
            if a.reason == REASON_MISPLACED and record.present_at(a.tile, a.t, intervals)
            and not any(landing.tile == a.tile and landing.t <= a.t <= gone for landing, gone in stays)]


@dataclass(frozen=True)
class RemovalOutcome:
    tile: int
    removed_at: float
    detected_at: float | None  # when inspection found it missing (its auction opened)
    found_by_robot_at: float | None  # when a robot found it missing first (placing on it)
    called_present: int  # scans that saw it and called it present while it was away
    back_at: float | None  # when it was physically in place again
    last_judged: str | None = None  # the last scan's word on it before anyone found it (or it came back)


@dataclass
class DetectionStats:
    removed: int = 0
    # the paper's figures: the inspection's last word on each removed tile
    reported_missing: int = 0  # "detected"
    reported_nothing: int = 0  # "undetermined": no scan saw it, or only undetermined
    left_present: int = 0  # "false positives": last reported present (or misplaced)
    present_called_missing: int = 0  # "false negatives": auctions opened for tiles that were there, lying right
    wrong_called_missing: int = 0  # auctions opened as missing for tiles lying wrong (misplaced: repaired later)
    # who found each removed tile first
    detected: int = 0  # inspection: its call opened the auction
    found_by_robot: int = 0  # a robot placing a tile on it, before inspection did
    undetermined: int = 0  # nobody
    # stricter than the paper
    missing_called_present: int = 0  # removals some single scan called present
    present_tiles_called_missing: int = 0  # (tile, stay in place) some single scan called missing
    present_judgements: int = 0  # (present tile, scan) pairs judged
    present_judged_missing: int = 0  # of those, called missing
    detection_delays: list[float] = field(default_factory=list)  # s of simulated time to the first finding
    by_type: dict[str, list[int]] = field(default_factory=dict)  # type -> [removed, reported missing, found]

    def add(self, other: DetectionStats) -> None:
        for name in ("removed", "reported_missing", "reported_nothing", "left_present", "present_called_missing",
                     "wrong_called_missing", "detected", "found_by_robot", "undetermined", "missing_called_present",
                     "present_tiles_called_missing", "present_judgements", "present_judged_missing"):
            setattr(self, name, getattr(self, name) + getattr(other, name))
        self.detection_delays += other.detection_delays
        for type_name, counts in other.by_type.items():
            mine = self.by_type.setdefault(type_name, [0] * len(counts))
            for k, count in enumerate(counts):
                mine[k] += count


def _first_announcement(record: TrialRecord, tile: int, reason: int, start: float, stop: float) -> float | None:
    return next(
        (a.t for a in record.announcements if a.tile == tile and a.reason == reason and start <= a.t <= stop), None
    )


def removal_outcomes(record: TrialRecord) -> list[RemovalOutcome]:
    intervals = record.presence_intervals()
    outcomes = []
    for removal in record.removals():
        back = next((a for a, _ in intervals.get(removal.tile, []) if a > removal.t), None)
        end = back if back is not None else float("inf")
        detected = _first_announcement(record, removal.tile, REASON_MISSING, removal.t, end)
        found = _first_announcement(record, removal.tile, REASON_FOUND_MISSING, removal.t, end)
        judged = [s for s in record.scans if removal.t < s.t < end and removal.tile in s.fresh]
        called_present = sum(1 for s in judged if s.states.get(removal.tile) == PRESENT)
        first_found = min((t for t in (detected, found) if t is not None), default=end)
        before = [s.states.get(removal.tile) for s in judged if s.t <= first_found]
        outcomes.append(RemovalOutcome(removal.tile, removal.t, detected, found, called_present, back,
                                       before[-1] if before else None))
    return outcomes


def detection_stats(record: TrialRecord) -> DetectionStats:
    stats = DetectionStats()
    intervals = record.presence_intervals()
    for outcome in removal_outcomes(record):
        stats.removed += 1
        per_type = stats.by_type.setdefault(record.tile_types.get(outcome.tile, "?"), [0, 0, 0])
        per_type[0] += 1
        if outcome.detected_at is not None or outcome.last_judged == MISSING:
            stats.reported_missing += 1
            per_type[1] += 1
        elif outcome.last_judged in (PRESENT, MISPLACED):
            stats.left_present += 1
        else:
            stats.reported_nothing += 1
        found = [t for t in (outcome.detected_at, outcome.found_by_robot_at) if t is not None]
        if found:
            per_type[2] += 1
            stats.detection_delays.append(min(found) - outcome.removed_at)
        if outcome.detected_at is not None:
            stats.detected += 1
        elif outcome.found_by_robot_at is not None:
            stats.found_by_robot += 1
        else:
            stats.undetermined += 1
        if outcome.called_present:
            stats.missing_called_present += 1
    stays = wrong_stays(record)
    for announcement in record.announcements:
        if announcement.reason == REASON_MISSING and record.present_at(announcement.tile, announcement.t, intervals):
            if record.lying_wrong_at(announcement.tile, announcement.t, stays):
                stats.wrong_called_missing += 1
            else:
                stats.present_called_missing += 1
    called_missing: set[tuple[int, float]] = set()
    for scan in record.scans:
        for tile, state in scan.states.items():
            if tile in scan.fresh and record.present_at(tile, scan.t, intervals) and not record.lying_wrong_at(
                    tile, scan.t, stays):
                stats.present_judgements += 1
                stats.present_judged_missing += state == MISSING
                if state == MISSING:
                    stay = next(a for a, b in intervals[tile] if a <= scan.t < b)
                    called_missing.add((tile, stay))
    stats.present_tiles_called_missing = len(called_missing)
    return stats


def false_missing_calls(record: TrialRecord, lying_wrong: bool = False) -> list[dict[str, float]]:
    """Auctions opened as missing for tiles that were physically in place and lying right (with
    `lying_wrong`: for tiles lying shifted, turned or of the wrong type instead): when, which tile."""
    intervals, stays = record.presence_intervals(), wrong_stays(record)
    return [
        {"t": a.t, "tile": a.tile}
        for a in record.announcements
        if a.reason == REASON_MISSING and record.present_at(a.tile, a.t, intervals)
        and record.lying_wrong_at(a.tile, a.t, stays) == lying_wrong
    ]


def allocation_rows(record: TrialRecord, robots: Iterable[str]) -> list[dict[str, str]]:
    """Table 2: one row per placement or removal, in time order, in the column of its robot.

    A removed tile appears in the column of the robot that had placed it, as in the paper.
    """
    robots = list(robots)
    last_placer: dict[int, str] = {}
    rows = []
    for event in sorted(record.events, key=lambda e: e.t):
        if event.kind == "placed":
            last_placer[event.tile] = event.robot
            label = f"{_pretty(record.tile_types.get(event.tile, '?'))} {event.tile}"
            rows.append({r: (label if r == event.robot else "") for r in robots} | {"t": f"{event.t:.0f}"})
        elif event.kind == "removed":
            owner = last_placer.get(event.tile, robots[0])
            rows.append({r: (f"Removed tile {event.tile}" if r == owner else "") for r in robots}
                        | {"t": f"{event.t:.0f}"})
    return rows


@dataclass(frozen=True)
class Interval:
    robot: str
    start: float
    end: float
    kind: str  # place, replace, take off, wait, failed, wait for room
    tile: int = 0


def schedule(record: TrialRecord) -> list[Interval]:
    """Per robot: placements (re-placements marked), take-offs of a repair, failed attempts, waits for
    supports and waits for room to stand, for the Gantt chart."""
    removed_before: set[int] = set()
    started: dict[str, tuple[float, int]] = {}
    intervals: list[Interval] = []
    for event in sorted(record.events, key=lambda e: e.t):
        if event.kind in GONE:
            removed_before.add(event.tile)
        if event.kind == "taken_off" and event.robot in started:
            t0, tile = started.pop(event.robot)
            intervals.append(Interval(event.robot, t0, event.t, "take off", tile))
        elif event.kind in ("place_started", "removal_started"):
            started[event.robot] = (event.t, event.tile)
        elif event.kind in ("placed", "refused", "dropped", "already_present") and event.robot in started:
            t0, tile = started.pop(event.robot)
            kind = "failed" if event.kind in ("refused", "dropped") else (
                "replace" if tile in removed_before else "place")
            intervals.append(Interval(event.robot, t0, event.t, kind, tile))
    waiting: dict[str, float] = {}
    for sample in sorted(record.statuses, key=lambda s: s.t):
        if sample.state == 1 and sample.robot not in waiting:  # RobotStatus.WAITING
            waiting[sample.robot] = sample.t
        elif sample.state != 1 and sample.robot in waiting:
            intervals.append(Interval(sample.robot, waiting.pop(sample.robot), sample.t, "wait"))
    intervals += [Interval(w.robot, w.since, w.since + w.seconds, "wait for room")
                  for w in record.room_waits if w.seconds]
    return intervals


def _pretty(type_name: str) -> str:
    return type_name.replace("_", " ").title()


def duplicate_placements(record: TrialRecord) -> list[dict[str, object]]:
    """Placements of a tile that was in place already: a robot placed it on top of itself (the
    world refuses, so this counts a bug of the world), or carried it there and found the place
    taken ("already_present": the tile was given to two robots, or called missing falsely)."""
    present: set[int] = set()
    found = []
    for event in sorted(record.events, key=lambda e: e.t):
        if event.kind == "placed":
            if event.tile in present:
                found.append({"t": event.t, "tile": event.tile, "robot": event.robot, "kind": "placed twice"})
            present.add(event.tile)
        elif event.kind in GONE:
            present.discard(event.tile)
        elif event.kind == "already_present":
            found.append({"t": event.t, "tile": event.tile, "robot": event.robot, "kind": "place taken"})
    return found


def lost_placements(record: TrialRecord) -> list[int]:
    """Tiles of the structure not in place when the trial ended (none when it completed)."""
    if record.complete():
        return []
    ended = max((e.t for e in record.events), default=0.0)
    intervals = record.presence_intervals()
    return sorted(t for t in record.tile_types if not record.present_at(t, ended, intervals))


def total_stats(records: list[TrialRecord]) -> DetectionStats:
    """The detection statistics of several trials together."""
    total = DetectionStats()
    for record in records:
        total.add(detection_stats(record))
    return total
