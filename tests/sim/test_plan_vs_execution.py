"""Where an executed build departs from its plan: per robot, planned work, placing and standing time (ROS-free)."""

from __future__ import annotations

import pytest
from conftest import STRUCTURES

from tiling_assembly.structure_file import load_structure
from tiling_assembly.time_model import TimeModel
from tiling_sim.plan_vs_execution import account_lines, planned_completion, robot_accounts
from tiling_sim.trial_record import PlanRecord, TrialRecord, WorldEvent

PAPER = load_structure(STRUCTURES / "paper_14.yaml")


def test_placing_and_standing_time_add_up_per_robot() -> None:
    record = TrialRecord(trial=0, seed=1, removals_planned=0, started_at=5.0)
    record.events = [
        WorldEvent(6.0, "place_started", 1, "robot1"),
        WorldEvent(7.0, "place_started", 6, "robot2"),
        WorldEvent(36.0, "placed", 1, "robot1"),
        WorldEvent(40.0, "place_started", 2, "robot1"),  # stood 4 s: waited for the team
        WorldEvent(45.0, "dropped", 2, "robot1"),  # a failed placement is placing time too
        WorldEvent(45.0, "place_started", 2, "robot1"),
        WorldEvent(70.0, "placed", 2, "robot1"),
        WorldEvent(39.0, "placed", 6, "robot2"),
        WorldEvent(20.0, "removed", 9),  # not a robot's
    ]
    model = TimeModel()
    robot1, robot2 = robot_accounts(record, PAPER, model)
    assert robot1.robot == "robot1" and robot1.tiles == [1, 2]
    assert robot1.placing == pytest.approx(30.0 + 5.0 + 25.0)
    assert robot1.standing == pytest.approx(1.0 + 4.0)
    assert robot1.finished == pytest.approx(65.0)
    assert robot1.planned_work == pytest.approx(model.workload(PAPER, [1, 2]))
    assert (robot2.placing, robot2.standing, robot2.finished) == pytest.approx((32.0, 2.0, 34.0))
    lines = account_lines([robot1, robot2], planned_makespan=60.0, makespan=65.0)
    assert "+8.3%" in lines[0] and lines[1].startswith("  robot1: 2 tiles")


def test_the_plan_completes_the_build_when_its_last_tile_is_placed_not_when_its_robot_is_back() -> None:
    """The plan's makespan ends with the last robot's walk back to a cache; the executed makespan
    ends when the last tile is placed. Robot2 is back at 100 s from tile 14, robot1 at 98 s from tile
    13: the build is complete when the later of 100 - walk(14) and 98 - walk(13) is reached."""
    model = TimeModel()
    plan = PlanRecord(t=0.0, revision=0, method="default", tasks={"robot1": [1, 13], "robot2": [2, 14], "robot3": []},
                      makespan=100.0, lower_bound=90.0, finishes={"robot1": 98.0, "robot2": 100.0, "robot3": 0.0})
    expected = max(98.0 - model.return_time(PAPER, 13), 100.0 - model.return_time(PAPER, 14))
    assert planned_completion(plan, PAPER, model) == pytest.approx(expected)
    assert expected < 100.0
    lines = account_lines([], planned_makespan=100.0, makespan=96.0, completion=expected)
    assert lines[1].startswith(f"  the plan places its last tile at {expected:.1f} s")
    assert planned_completion(PlanRecord(0.0, 0, "paper", {"robot1": [1]}, 30.0, 30.0), PAPER, model) is None
