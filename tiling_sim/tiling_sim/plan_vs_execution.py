"""Where an executed build departs from its plan (the planner's time model, paper section 2.1).

Per assembly robot: the work the planner's `TimeModel` predicts for the tiles the robot placed
(with the drive from where the robot stood to its first tile's cache, when its start is known),
beside the simulated time the robot spent in placements (from `place_started` to the placement's
end, as the world saw it) and the time it stood between them or before its first (waiting for a
support, for the plan, for the team's next decision). Work that runs longer or shorter than
predicted is the time model's error; standing time is what the plan did not foresee.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from tiling_assembly.structure import Structure
from tiling_assembly.time_model import TimeModel
from tiling_sim.trial_record import PlanRecord, TrialRecord

Point2 = tuple[float, float]
PLACEMENT_ENDS = frozenset({"placed", "dropped", "already_present", "refused"})


@dataclass(frozen=True)
class RobotAccount:
    robot: str
    tiles: list[int]  # placed by this robot, in order
    planned_work: float  # s, the time model's cost of those tiles, the first drive included
    first_drive: float  # s, the time model's drive from the start to the first tile's cache
    placing: float  # s of simulated time in placements, failed ones included
    standing: float  # s between placements and before the first
    finished: float  # s after the build started, when its last placement ended

    def as_dict(self) -> dict[str, object]:
        return {"robot": self.robot, "tiles": self.tiles, "planned_work": round(self.planned_work, 2),
                "first_drive": round(self.first_drive, 2),
                "placing": round(self.placing, 2), "standing": round(self.standing, 2),
                "finished": round(self.finished, 2)}


def robot_accounts(
    record: TrialRecord, structure: Structure, model: TimeModel, starts: Mapping[str, Point2] | None = None
) -> list[RobotAccount]:
    """One account per robot that started a placement in `record`, by robot name; `starts`: where
    each robot stood when the build started."""
    robots = sorted({e.robot for e in record.events if e.kind == "place_started"})
    return [_account(record, structure, model, robot, (starts or {}).get(robot)) for robot in robots]


def _account(
    record: TrialRecord, structure: Structure, model: TimeModel, robot: str, start: Point2 | None
) -> RobotAccount:
    events = sorted((e for e in record.events if e.robot == robot), key=lambda e: e.t)
    placing, standing, last_end, started = 0.0, 0.0, record.started_at, None
    for event in events:
        if event.kind == "place_started":
            standing += event.t - last_end
            started = event.t
        elif event.kind in PLACEMENT_ENDS and started is not None:
            placing += event.t - started
            last_end, started = event.t, None
    tiles = [e.tile for e in events if e.kind == "placed"]
    first_drive = 0.0
    if start is not None and tiles:
        first_drive = float(model.start_trips(structure, [start])[0][list(structure.tiles).index(tiles[0])])
    return RobotAccount(robot=robot, tiles=tiles, planned_work=first_drive + model.workload(structure, tiles),
                        first_drive=first_drive, placing=placing, standing=standing,
                        finished=last_end - record.started_at)


def planned_completion(plan: PlanRecord, structure: Structure, model: TimeModel) -> float | None:
    """When the plan places its last tile (s): a robot's planned finish less its walk back from its
    last tile, the latest of them. The plan's makespan ends with that walk; a build is complete
    when its last tile is placed. None when the plan has no finish times."""
    ends = [plan.finishes[robot] - model.return_time(structure, tiles[-1])
            for robot, tiles in plan.tasks.items() if tiles and robot in plan.finishes]
    return max(ends) if ends else None


def account_lines(accounts: list[RobotAccount], planned_makespan: float | None, makespan: float | None,
                  completion: float | None = None) -> list[str]:
    """The accounts as report lines; `completion`: when the plan places its last tile."""
    lines = []
    if planned_makespan and makespan:
        lines.append(f"Plan vs execution (trial without faults): makespan {makespan:.1f} s executed, "
                     f"{planned_makespan:.1f} s planned ({100.0 * (makespan / planned_makespan - 1):+.1f}%)")
    if completion and makespan:
        lines.append(f"  the plan places its last tile at {completion:.1f} s (its makespan adds the walk back): "
                     f"executed {100.0 * (makespan / completion - 1):+.1f}% of that")
    for a in accounts:
        lines.append(f"  {a.robot}: {len(a.tiles)} tiles, work planned {a.planned_work:.1f} s "
                     f"(first drive {a.first_drive:.1f} s), placing "
                     f"{a.placing:.1f} s ({100.0 * (a.placing / max(a.planned_work, 1e-9) - 1):+.1f}%), "
                     f"standing {a.standing:.1f} s, done at {a.finished:.1f} s")
    return lines
