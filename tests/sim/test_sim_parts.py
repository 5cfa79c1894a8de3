"""The ROS-free parts of the split simulator: settings, where robots stand, the clock's hold for a
scan, the Kinect's frame cycle, the world's referee, alarms and the overhead cameras."""

from __future__ import annotations

import math
import re
from dataclasses import fields

import pytest
import yaml
from conftest import REPO, STRUCTURES

from tiling_assembly.structure_file import load_structure
from tiling_sim.alarms import Alarms
from tiling_sim.faults import FaultInjector
from tiling_sim.overhead_cameras import OverheadCameras
from tiling_sim.scan_cycle import ScanCycle
from tiling_sim.scan_hold import ScanHold
from tiling_sim.sim_clock import Pace
from tiling_sim.sim_settings import (
    SETTINGS_OF_NODE,
    RobotBodySettings,
    SimLayout,
    ViBodySettings,
    WorldSettings,
)
from tiling_sim.whereabouts import Whereabouts, standing_at
from tiling_sim.world import PhysicalWorld
from tiling_sim.world_referee import Outcome, WorldReferee

PAPER = load_structure(STRUCTURES / "paper_14.yaml")
STRUCTURE = str(STRUCTURES / "paper_14.yaml")


def _parameters(name: str) -> dict:  # type: ignore[type-arg]
    return yaml.safe_load((REPO / "config" / name).read_text())["/**"]["ros__parameters"]


# --- settings -------------------------------------------------------------------------------
def test_every_value_of_the_config_file_is_some_nodes_and_accepted_by_it() -> None:
    values = _parameters("tiling_sim.yaml")
    owners = {name: [node for node, cls in SETTINGS_OF_NODE.items() if name in cls.names()] for name in values}
    assert not [name for name, nodes in owners.items() if not nodes], "values no simulator node declares"
    for node, cls in SETTINGS_OF_NODE.items():
        mine = {name: value for name, value in values.items() if name in cls.names()}
        cls.from_values({**mine, "structure_file": STRUCTURE}, node)  # raises on a bad value


def test_code_defaults_are_the_config_files_except_the_start_positions() -> None:
    """robot_start_xy: the file's fit its two robots; the code's default spreads any team."""
    values = _parameters("tiling_sim.yaml")
    for cls in SETTINGS_OF_NODE.values():
        defaults = cls()
        for name in set(values) & set(cls.names()) - {"robot_start_xy"}:
            assert getattr(defaults, name) == pytest.approx(values[name]), f"{cls.__name__}.{name}"


def test_the_kinect_shares_vi_nodes_camera_parameters() -> None:
    camera = {name: value for name, value in _parameters("vi_node.yaml").items() if name in ViBodySettings.names()}
    assert set(camera) >= {"camera_xyz", "camera_rpy", "intrinsics", "intrinsics_size", "robot_size"}
    settings = ViBodySettings.from_values({**camera, "structure_file": STRUCTURE})
    assert settings.camera_rpy == camera["camera_rpy"] and settings.intrinsics_size == [640, 480]


def test_every_setting_has_a_description_and_the_layout_is_shared() -> None:
    for cls in SETTINGS_OF_NODE.values():
        assert all(cls.description(f.name) for f in fields(cls))
        assert set(SimLayout.names()) <= set(cls.names())


@pytest.mark.parametrize("values, message", [
    ({"structure_file": ""}, "parameter 'structure_file' is required"),
    ({"real_time_factor": 0.0}, "'real_time_factor' and 'clock_step' must be positive"),
    ({"real_time_factor": "fast"}, "parameter 'real_time_factor' has the wrong type"),
    ({"removals": 1.5}, "parameter 'removals' has the wrong type"),
    ({"wait_for_start": 1}, "parameter 'wait_for_start' has the wrong type"),
    ({"robot_start_xy": [0.0, 1.0, 2.0]}, "needs 2 numbers per robot (2), got 3"),
    ({"robot_names": [""]}, "'robot_names' is empty"),
    ({"drop_probability": 2.0}, "must lie in [0, 1]"),
    ({"place_time": 1.0}, "unknown parameter 'place_time'"),
    ({"vi_robot_names": ["vi1", "vi1"]}, "'vi_robot_names' needs one or more different names"),
    ({"vi_robot_names": ["vi1", "vi2"], "vi_start_pose": [0.0, 1.0]}, "'vi_start_pose' needs x, y, yaw"),
])
def test_bad_world_settings_are_named_in_one_line(values: dict, message: str) -> None:  # type: ignore[type-arg]
    with pytest.raises(ValueError, match="^sim_world: .*" + re.escape(message)):
        WorldSettings.from_values({"structure_file": STRUCTURE, **values}, "sim_world")


def test_integers_count_as_floats_and_start_positions_spread_round_the_structure() -> None:
    settings = RobotBodySettings.from_values({"structure_file": STRUCTURE, "place_time": 9})
    assert settings.place_time == 9.0 and isinstance(settings.place_time, float)
    starts = settings.robot_starts(PAPER)
    assert list(starts) == ["robot1", "robot2"] and starts["robot1"] != starts["robot2"]
    given = RobotBodySettings(robot_start_xy=[1.0, 2.0, 3.0, 4.0])
    assert given.robot_starts(PAPER) == {"robot1": (1.0, 2.0), "robot2": (3.0, 4.0)}
    assert settings.motion().place_time == 9.0 and settings.motion().base_size == (0.33, 0.33)


def test_several_vi_robots_start_round_the_structure_unless_placed() -> None:
    one = WorldSettings.from_values({"structure_file": STRUCTURE})
    assert one.vi_starts(PAPER) == {"vi": (0.9, 0.0, pytest.approx(math.pi))}
    two = WorldSettings.from_values({"structure_file": STRUCTURE, "vi_robot_names": ["vi1", "vi2"]})
    starts = two.vi_starts(PAPER)
    (low, high) = PAPER.bounds
    centre = ((low[0] + high[0]) / 2, (low[1] + high[1]) / 2)
    assert starts["vi1"] == (0.9, 0.0, pytest.approx(math.pi))
    x, y, yaw = starts["vi2"]  # half a turn round the centre, still facing it
    assert (x + 0.9 - 2 * centre[0], y - 2 * centre[1]) == (pytest.approx(0.0), pytest.approx(0.0))
    assert math.cos(yaw) == pytest.approx(1.0)
    placed = WorldSettings.from_values({"structure_file": STRUCTURE, "vi_robot_names": ["vi1", "vi2"],
                                        "vi_start_pose": [1.0, 0.0, 3.0, -1.0, 0.0, 0.0]})
    assert placed.vi_starts(PAPER) == {"vi1": (1.0, 0.0, 3.0), "vi2": (-1.0, 0.0, 0.0)}


# --- where the robots stand -----------------------------------------------------------------
def test_a_robot_stands_where_its_body_said_from_the_moment_it_said() -> None:
    where = Whereabouts({"robot1": (0.0, 0.0, 0.0), "vi": (1.0, 0.0, math.pi)})
    where.expect("robot1", 12.0, (2.0, 0.0, 0.0))
    where.expect("robot1", 5.0, (1.0, 0.0, 0.0))  # news may come out of order
    assert where.arrive(4.9) == [] and where.poses["robot1"] == (0.0, 0.0, 0.0)
    assert where.arrive(5.0) == ["robot1"] and where.poses["robot1"] == (1.0, 0.0, 0.0)
    assert where.arrive(20.0) == ["robot1"] and where.poses["robot1"] == (2.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="unknown robot 'robot9'"):
        where.expect("robot9", 1.0, (0.0, 0.0, 0.0))


def test_a_body_whose_clock_lags_renders_from_where_the_world_has_it() -> None:
    """A busy host's VI body still counted down its drive when the world, past the arrival, stamped a frame
    and the overhead pose: the frame came from the start, the pose from the goal, 10-13 cm apart, and
    45% of a CI run's scans failed to align. The body renders from where the world has it at the stamp."""
    start, goal = (1.0, 0.0, math.pi), (0.8, 0.5, 2.0)
    where = Whereabouts({"vi": start})
    where.expect("vi", 30.0, goal)
    for t in (29.0, 30.0, 31.5):
        where.arrive(t)
        assert standing_at(t, start, (30.0, goal)) == where.poses["vi"]
    assert standing_at(29.0, start, (30.0, goal)) == start and standing_at(31.5, start, (30.0, goal)) == goal
    assert standing_at(31.5, goal, None) == goal


def test_overhead_errors_stay_while_a_robot_stands_and_respect_the_papers_bounds() -> None:
    cameras = OverheadCameras(3, 0.05, math.radians(10), ["robot1", "vi"])
    seen = cameras.observe("robot1", (1.0, 2.0, 0.0))
    assert cameras.observe("robot1", (1.0, 2.0, 0.0)) == seen
    for _ in range(200):
        cameras.stopped("robot1")
        x, y, yaw = cameras.observe("robot1", (1.0, 2.0, 0.0))
        assert math.hypot(x - 1.0, y - 2.0) <= 0.05 and abs(yaw) <= math.radians(10)
    again = OverheadCameras(3, 0.05, math.radians(10), ["robot1", "vi"])
    assert again.observe("robot1", (1.0, 2.0, 0.0)) == seen  # reproducible from the seed


# --- the clock's pace for a scan --------------------------------------------------------------
def test_the_clock_stops_for_a_scan_the_explorer_waits_for_until_it_is_judged_and_it_decides() -> None:
    hold = ScanHold(limit=30.0)
    assert hold.pace(0.0) is Pace.FAST and hold.ceiling() is None
    hold.hold(5_000_000_000, wall=1.0, stop=True, period=2.0, decision_window=0.5)
    assert hold.pace(1.0) is Pace.STOPPED  # rendering and judging cost this host's time, not the robot's
    assert not hold.judged(4_000_000_000, wall=1.2)  # an older scan's verdict
    assert hold.pace(1.3) is Pace.STOPPED
    assert hold.judged(5_000_000_000, wall=1.4)
    assert hold.pace(1.8) is Pace.STOPPED  # the explorer decides where next
    assert hold.pace(1.95) is Pace.FAST
    assert hold.ceiling() == pytest.approx(7.0)  # ... and time runs up to a period after the scan
    assert not hold.judged(5_000_000_000, wall=2.0)
    hold.hold(8_000_000_000, wall=3.0, stop=True, decision_window=0.5)
    hold.judged(8_000_000_000, wall=3.1)
    hold.moved()  # the explorer drove on before its window ended
    assert hold.pace(3.2) is Pace.FAST


def test_the_clock_stays_at_its_start_until_every_vi_robot_has_set_off() -> None:
    """Its explorer waits some wall time to find the other VI robots: a first goal that came when a
    busy host let it (once 0.8 s of wall time, 15 s simulated, after the start) started the VI
    robot's whole path late, and every detection with it."""
    hold = ScanHold(limit=30.0)
    hold.starting(["vi1", "vi2"], wall=100.0, patience=12.0)
    hold.hold(0, wall=100.1, robot="vi1", stop=False, period=5.0)  # its first frame, streamed
    assert hold.pace(100.5) is Pace.STOPPED
    hold.moved("vi1", until=20.0)
    assert hold.pace(101.0) is Pace.STOPPED  # vi2 still chooses
    hold.moved("vi2", until=None)
    assert hold.pace(101.0) is Pace.FAST
    alone = ScanHold(limit=30.0)
    alone.starting(["vi"], wall=100.0, patience=12.0)
    assert alone.pace(111.9) is Pace.STOPPED
    assert alone.lapsed(112.1) == []  # no fault: an explorer may have been stopped
    assert alone.pace(112.1) is Pace.FAST


def test_a_streamed_scan_holds_the_clock_a_period_after_it_until_the_next_snapshot() -> None:
    """A vi_node that falls behind holds time back: the next frame comes a period later however
    long it took to judge this one (a busy host judges the same scans as a quiet one)."""
    hold = ScanHold(limit=30.0)
    hold.hold(5_000_000_000, wall=1.0, stop=False, period=2.0)
    assert hold.pace(1.0) is Pace.FAST and hold.ceiling() == pytest.approx(7.0)
    hold.judged(5_000_000_000, wall=1.1)
    assert hold.ceiling() == pytest.approx(7.0)  # judged early: the clock still waits for the next frame
    hold.hold(7_000_000_000, wall=1.3, stop=False, period=2.0)
    assert hold.ceiling() == pytest.approx(9.0)
    hold.moved()  # the base sets off: no frames on the way
    assert hold.ceiling() is None and hold.pace(1.4) is Pace.FAST
    # a drive to a viewpoint: time does not pass the arrival, settled, until the frame taken there
    hold.moved(until=12.2)
    assert hold.ceiling() == pytest.approx(12.2) and hold.pace(1.5) is Pace.FAST
    assert not hold.lapsed(100.0, now=11.0)  # the drive itself may take its time
    hold.hold(11_000_000_000, wall=100.5, stop=False, period=2.0)  # asked for before it set off
    assert hold.ceiling() == pytest.approx(12.2)
    hold.hold(12_200_000_000, wall=101.0, stop=True, period=2.0)
    assert hold.pace(101.0) is Pace.STOPPED and hold.ceiling() == pytest.approx(14.2)


def test_a_hold_nobody_ends_lapses() -> None:
    hold = ScanHold(limit=2.0)
    hold.hold(1, wall=10.0)
    assert not hold.lapsed(11.9) and hold.pace(11.9) is Pace.STOPPED
    assert hold.lapsed(12.1) and hold.pace(12.1) is Pace.FAST
    assert not hold.lapsed(20.0)
    # a ceiling lapses `limit` after the clock reached it, not after the snapshot
    hold.hold(1_000_000_000, wall=20.0, stop=False, period=2.0)
    assert not hold.lapsed(30.0, now=2.5) and hold.ceiling() == pytest.approx(3.0)
    assert not hold.lapsed(31.0, now=3.0)
    assert not hold.lapsed(32.9, now=3.0)
    assert hold.lapsed(33.1, now=3.0) == [""] and hold.ceiling() is None


def test_with_two_vi_robots_the_tightest_hold_counts() -> None:
    hold = ScanHold(limit=2.0)
    hold.hold(5_000_000_000, wall=1.0, robot="vi1", stop=False, period=3.0)
    hold.hold(6_000_000_000, wall=1.1, robot="vi2", stop=True, period=3.0)
    assert hold.pace(1.1) is Pace.STOPPED and hold.ceiling() == pytest.approx(8.0)
    assert not hold.judged(6_000_000_000, robot="vi1", wall=1.2)  # vi2's stamp, vi1's name: vi1 did not stop
    assert hold.judged(6_000_000_000, robot="vi2", wall=1.2) and hold.pace(1.2) is Pace.FAST
    hold.moved("vi1")
    assert hold.ceiling() == pytest.approx(9.0)
    assert hold.lapsed(3.2, now=9.0) == []  # vi2's ceiling was only just reached
    assert hold.lapsed(5.3, now=9.0) == ["vi2"] and hold.ceiling() is None


# --- the Kinect's frames ----------------------------------------------------------------------
def test_frames_come_every_period_once_the_last_is_judged() -> None:
    cycle = ScanCycle(period=1.0, verdict_timeout=3.0)
    assert cycle.start(0.5, wall=0.0) is None
    frame = cycle.start(1.0, wall=0.0)
    assert frame is not None and not frame.held
    assert cycle.snapshot_arrived(frame, 1_000_000_000)
    assert cycle.start(5.0, wall=0.1) is None  # one frame at a time
    cycle.published(frame, wall=0.2)
    assert cycle.judged(999_000_000, wall=0.3) is None  # about an older scan
    judged = cycle.judged(1_000_000_000, wall=0.35)
    assert judged is not None and judged[0] is frame and judged[1] == pytest.approx(0.15)
    assert cycle.start(1.5, wall=0.4) is None and cycle.start(2.0, wall=0.4) is not None


def test_the_next_frame_is_a_period_after_the_world_time_a_frame_shows() -> None:
    cycle = ScanCycle(period=1.0, verdict_timeout=3.0)
    frame = cycle.start(1.0, wall=0.0)  # this body's clock lags the world's
    assert frame is not None and cycle.snapshot_arrived(frame, 1_800_000_000)
    cycle.published(frame, wall=0.1)
    cycle.judged(1_800_000_000, wall=0.2)
    assert cycle.start(2.5, wall=0.3) is None and cycle.start(2.8, wall=0.3) is not None


def test_after_an_arrival_the_base_settles_and_the_next_frame_holds_the_clock() -> None:
    cycle = ScanCycle(period=1.0, verdict_timeout=3.0)
    cycle.departed()
    assert cycle.start(10.0, wall=0.0) is None  # no frames while the base drives
    cycle.arrived(10.0)
    assert cycle.start(10.1, wall=0.0) is None
    frame = cycle.start(10.2, wall=0.0)
    assert frame is not None and frame.held
    cycle.snapshot_arrived(frame, 10_200_000_000)
    cycle.published(frame, wall=0.5)
    cycle.judged(10_200_000_000, wall=0.6)
    following = cycle.start(11.2, wall=0.7)
    assert following is not None and not following.held


def test_a_frame_is_given_up_without_a_snapshot_or_a_verdict_in_time() -> None:
    cycle = ScanCycle(period=1.0, verdict_timeout=3.0)
    frame = cycle.start(1.0, wall=0.0)
    assert frame is not None
    assert cycle.overdue(2.9) is None
    assert cycle.overdue(3.1) is frame
    assert not cycle.snapshot_arrived(frame, 1)  # the late snapshot is not rendered
    frame = cycle.start(2.0, wall=4.0)
    assert frame is not None and cycle.snapshot_arrived(frame, 2_000_000_000)
    assert cycle.overdue(100.0) is None  # rendering takes what it takes
    cycle.published(frame, wall=100.0)
    assert cycle.overdue(102.0) is None and cycle.overdue(103.5) is frame
    frame = cycle.start(3.0, wall=104.0)
    assert frame is not None
    cycle.failed(frame)
    assert cycle.frame is None


def test_the_world_waits_for_vi_node_only_while_it_answers() -> None:
    """From the start vi_node is counted on; after it missed a verdict, frames go to whoever views
    them without holding the world back, and are given up sooner, until it answers one again."""
    cycle = ScanCycle(period=1.0, verdict_timeout=15.0)
    frame = cycle.start(1.0, wall=0.0)
    assert frame is not None and cycle.answering
    cycle.snapshot_arrived(frame, 1_000_000_000)
    cycle.published(frame, wall=0.1)
    assert cycle.overdue(3.2) is None  # the first verdict is waited for too
    assert cycle.overdue(15.2) is frame and not cycle.answering  # nobody judges
    frame = cycle.start(2.0, wall=15.3)
    cycle.snapshot_arrived(frame, 2_000_000_000)
    cycle.published(frame, wall=15.4)
    assert cycle.overdue(18.5) is frame  # a viewer's timeout
    frame = cycle.start(3.0, wall=18.6)
    cycle.snapshot_arrived(frame, 3_000_000_000)
    cycle.published(frame, wall=18.7)
    assert cycle.judged(3_000_000_000, wall=18.9) is not None and cycle.answering
    frame = cycle.start(4.0, wall=19.0)
    cycle.snapshot_arrived(frame, 4_000_000_000)
    cycle.published(frame, wall=19.1)
    assert cycle.overdue(25.0) is None  # a busy vi_node is waited for
    assert cycle.overdue(34.2) is frame and not cycle.answering  # a dead one is not


def test_a_goal_decided_on_a_frame_sets_off_at_a_time_that_frame_sets_not_when_it_came() -> None:
    """The explorer stamps a goal with the frame whose verdict it chose on: the base sets off at that
    frame's time if the clock stood still for it, a period later if it was streamed (the clock cannot
    pass that before the verdict), whenever the goal reaches the body."""
    cycle = ScanCycle(period=5.0, verdict_timeout=15.0)
    cycle.arrived(10.0)
    held = cycle.start(10.2, wall=0.0)
    assert held is not None and held.held and cycle.snapshot_arrived(held, 10_200_000_000)
    cycle.published(held, wall=0.1)
    cycle.judged(10_200_000_000, wall=0.2)
    streamed = cycle.start(15.2, wall=0.3)
    assert streamed is not None and not streamed.held and cycle.snapshot_arrived(streamed, 15_200_000_000)
    assert cycle.departure(10_200_000_000, now=10.2) == pytest.approx(10.2)
    assert cycle.departure(15_200_000_000, now=16.0) == pytest.approx(20.2)  # came early: waits
    assert cycle.departure(15_200_000_000, now=23.0) == pytest.approx(20.2)  # came late: as if in time
    assert cycle.departure(12_000_000_000, now=16.0) == 16.0  # no frame of that time: now
    assert cycle.departure(15_200_000_000, now=40.0) == 40.0  # far off: a stale goal sets off now
    cycle.published(streamed, wall=0.4)
    cycle.judged(15_200_000_000, wall=0.5)
    for k in range(1, 12):  # only the latest frames are remembered
        frame = cycle.start(15.2 + 5 * k, wall=1.0 + k)
        assert frame is not None and cycle.snapshot_arrived(frame, 15_200_000_000 + 5_000_000_000 * k)
        cycle.published(frame, wall=1.0 + k)
        cycle.judged(15_200_000_000 + 5_000_000_000 * k, wall=1.0 + k)
    assert cycle.departure(10_200_000_000, now=11.0) == 11.0 and len(cycle.taken) == 8


# --- the world's referee ----------------------------------------------------------------------
def test_placement_steps_give_the_old_events_in_order() -> None:
    referee = WorldReferee(PhysicalWorld(PAPER), FaultInjector(seed=1))
    assert referee.starting("robot1", 99).outcome is Outcome.UNKNOWN_TILE
    start = referee.starting("robot1", 4)  # its supports may be there by the time it is placed
    assert start.outcome is Outcome.OK and start.events == [("place_started", {"tile": 4, "robot": "robot1"})]
    refused = referee.placing("robot1", 4)
    assert refused.outcome is Outcome.SUPPORT_MISSING and refused.absent_supports == [1, 2, 3, 6]
    assert refused.events[0][0] == "refused" and "support 1, 2, 3, 6" in refused.events[0][1]["reason"]
    assert referee.picked("robot1", 1).outcome is Outcome.OK
    placed = referee.placing("robot2", 1)
    assert placed.outcome is Outcome.OK and placed.events == [("placed", {"tile": 1, "robot": "robot2"})]
    again = referee.placing("robot1", 1)
    assert again.outcome is Outcome.ALREADY_PRESENT and again.events[0][0] == "already_present"
    assert referee.starting("robot1", 1).outcome is Outcome.ALREADY_PRESENT


def test_completion_is_told_once_and_again_after_a_removal() -> None:
    faults = FaultInjector(seed=1, removal_times=[50.0])
    referee = WorldReferee(PhysicalWorld(PAPER), faults)
    kinds = [kind for tile in _bottom_up() for kind, _ in referee.placing("robot1", tile).events]
    assert kinds.count("complete") == 1 and kinds[-1] == "complete"
    assert referee.remove_due(49.0) is None
    removed = referee.remove_due(50.0)
    assert removed is not None and removed[0] == "removed"
    tile = removed[1]["tile"]
    assert [kind for kind, _ in referee.placing("robot2", tile).events] == ["placed", "complete"]


def _bottom_up() -> list[int]:
    placed: list[int] = []
    while len(placed) < len(PAPER.tiles):
        placed += [t for t in sorted(PAPER.tiles) if t not in placed
                   and all(s in placed for s in PAPER.supports.get(t, ()))]
    return placed


def test_a_tile_slips_at_the_chosen_rate() -> None:
    referee = WorldReferee(PhysicalWorld(PAPER), FaultInjector(seed=4, drop_probability=1.0))
    dropped = referee.picked("robot2", 3)
    assert dropped.outcome is Outcome.DROPPED and dropped.events == [("dropped", {"tile": 3, "robot": "robot2"})]
    assert "slipped from robot2's gripper" in dropped.reason


# --- alarms -----------------------------------------------------------------------------------
def test_alarms_wake_in_time_order_then_in_the_order_set() -> None:
    alarms = Alarms()
    woken: list[str] = []
    alarms.set(2.0, lambda: woken.append("b"))
    alarms.set(1.0, lambda: woken.append("a"))
    alarms.set(2.0, lambda: woken.append("c"))
    for wake in alarms.due(1.5):
        wake()
    assert woken == ["a"] and len(alarms) == 2
    for wake in alarms.due(2.0):
        wake()
    assert woken == ["a", "b", "c"] and len(alarms) == 0
