"""The split simulator as real ROS 2 processes: the world, an assembly robot's body and the VI
robot's body, each reading the whole of config/tiling_sim.yaml (and vi_node.yaml) as the experiment
gives it, and what a team sees of them: placements with the old phases, durations, results and
events; the robots where they truly stand in the world's snapshot; Kinect frames stamped with the
time of the world they show, beside the overhead poses of that time."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import REPO, STRUCTURES, ros2_command, stop_node_processes
from geometry_msgs.msg import PoseStamped
from rclpy.action import ActionClient
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from ros_helpers.isolated_domains import fresh_domain
from ros_helpers.spinning import spin_until
from rosgraph_msgs.msg import Clock as ClockMsg
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Empty, String

from tiling_assembly.polygons import convex_hull_2d
from tiling_assembly.structure_file import load_structure
from tiling_assembly_msgs.action import NavigateTo, PlaceTile
from tiling_assembly_msgs.msg import SimMotion
from tiling_assembly_msgs.srv import SimSnapshot
from tiling_ros.qos import SIM_EVENTS, SIM_MOTION
from tiling_ros.stamps import stamp_to_nanoseconds
from tiling_sim.robot_motion import placement_phases
from tiling_sim.scan_bag import read_truth
from tiling_sim.sim_settings import RobotBodySettings
from vi_node.classify_bag import read_recording

pytestmark = pytest.mark.ros

PAPER_FILE = STRUCTURES / "paper_14.yaml"
PAPER = load_structure(PAPER_FILE)
START = (-0.6, -0.9)  # robot1's start in config/tiling_sim.yaml
PLACEMENT_EVENTS = {"place_started", "dropped", "placed", "already_present", "refused", "complete"}
PHASE_END_ROUNDING = 1e-6  # s: a phase ends at a /clock stamp, whole nanoseconds
DISCOVERY_SETTLING = 2.0  # s: long enough for the server side to discover a newly seen client


def _command(executable: str, namespace: str | None, *extra: str) -> list[str]:
    return [ros2_command(), "run", "tiling_sim", executable, "--ros-args",
            *(["-r", f"__ns:={namespace}"] if namespace else []),
            "--params-file", str(REPO / "config" / "vi_node.yaml"),
            "--params-file", str(REPO / "config" / "tiling_sim.yaml"),
            "-p", f"structure_file:={PAPER_FILE}", *extra]


class Simulator:
    """sim_world, /robot1's sim_robot and /vi's sim_vi on a ROS domain of their own, and a node of
    the test that watches them; `world_later`: the world is started by `start_world`."""

    def __init__(self, world_later: bool = False, world_arguments: tuple[str, ...] = (),
                 vi_arguments: tuple[str, ...] = ()) -> None:
        self.domain = fresh_domain()
        self.world_arguments = world_arguments
        body = ("-p", "use_sim_time:=true")
        self.processes = {
            "sim_robot": self._start(_command("sim_robot", "/robot1", *body)),
            "sim_vi": self._start(_command("sim_vi", "/vi", *body, *vi_arguments)),
        }
        if not world_later:
            self.start_world()
        self.context = self.domain.context
        self.node = Node("sim_processes_test", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.events: list[dict[str, Any]] = []
        self.clouds: list[PointCloud2] = []
        self.vi_poses: list[PoseStamped] = []
        self.node.create_subscription(String, "/sim/events", lambda m: self.events.append(json.loads(m.data)),
                                      SIM_EVENTS)
        self.node.create_subscription(PointCloud2, "/vi/camera/depth/points", self.clouds.append,
                                      QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        self.node.create_subscription(PoseStamped, "/vi/overhead_pose", self.vi_poses.append, 50)
        self.place = ActionClient(self.node, PlaceTile, "/robot1/place_tile")
        self.snapshot = self.node.create_client(SimSnapshot, "/sim/snapshot")

    def start_world(self) -> None:
        self.processes["sim_world"] = self._start(_command("sim_world", None, "-p", "removals:=0",
                                                           *self.world_arguments))

    def _start(self, command: list[str]) -> subprocess.Popen[str]:
        return subprocess.Popen(command, cwd=REPO, env=self.domain.environ(), stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)

    def wait_for_the_body(self, timeout: float = 60.0) -> None:
        """Until sim_robot serves place_tile, and a little longer: discovery is not symmetric, and
        a goal sent the moment this side sees the server can be answered before the server knows
        this side's reply reader, and the answer lost (once in a full run, on a fresh clone)."""
        assert self.spin_until(self.place.server_is_ready, timeout), "sim_robot never served place_tile"
        self.spin_until(lambda: False, DISCOVERY_SETTLING)

    def spin_until(self, predicate: Callable[[], bool], timeout: float) -> bool:
        return spin_until(self.executor, predicate, timeout)

    def call(self, future: Any, timeout: float = 30.0) -> Any:
        assert self.spin_until(future.done, timeout), "no answer in time"
        return future.result()

    def place_tile(self, tile_id: int, on_feedback: Callable[[Any], None] = lambda _f: None, like: int = 0) -> Any:
        """Place `tile_id` (where tile `like` goes, if given); the result."""
        return self.call(self.send_placement(tile_id, on_feedback, like).get_result_async(), timeout=60.0).result

    def send_placement(self, tile_id: int, on_feedback: Callable[[Any], None] = lambda _f: None,
                       like: int = 0) -> Any:
        """The accepted goal's handle."""
        tile = PAPER.tiles[like or tile_id]
        goal = PlaceTile.Goal(tile_id=tile_id, tile_type=tile.type_name)
        goal.pose.header.frame_id = "map"
        goal.pose.pose.position.x, goal.pose.pose.position.y = float(tile.position[0]), float(tile.position[1])
        goal.cache.x, goal.cache.y = PAPER.caches[tile.type_name]
        handle = self.call(self.place.send_goal_async(goal, feedback_callback=on_feedback))
        assert handle.accepted
        return handle

    def close(self) -> dict[str, str]:
        self.executor.shutdown()
        self.node.destroy_node()
        return stop_node_processes(self.processes)


@pytest.fixture(scope="module")
def sim() -> Iterator[Simulator]:
    bed = Simulator()
    try:
        bed.wait_for_the_body()
        assert bed.spin_until(bed.snapshot.service_is_ready, 10.0), "sim_world never served /sim/snapshot"
        yield bed
    finally:
        outputs = bed.close()  # every process stops cleanly at Ctrl-C
        assert not any("ERROR" in output for output in outputs.values()), outputs


def test_a_placement_has_the_old_phases_duration_result_and_events(sim: Simulator) -> None:
    seen: list[tuple[int, list[Any]]] = []

    def on_feedback(feedback: Any) -> None:
        phase = feedback.feedback.phase
        robots = None
        if phase == PlaceTile.Feedback.DRIVING_TO_STRUCTURE:  # it just picked the tile at its cache
            robots = sim.snapshot.call_async(SimSnapshot.Request())
        seen.append((phase, [robots]))

    result = sim.place_tile(1, on_feedback)
    assert result.error_code == PlaceTile.Result.SUCCEEDED, result.message
    motion = RobotBodySettings().motion()
    footprints = [convex_hull_2d(t.vertices[:, :2]) for t in PAPER.tiles.values()]
    tile = PAPER.tiles[1]
    cache = PAPER.caches[tile.type_name]
    phases = placement_phases(motion, START, cache, (tile.position[0], tile.position[1]), footprints)
    assert [phase for phase, _ in seen] == [1, 2, 3, 4, 5, 6]
    planned = sum(p.duration for p in phases)
    # the world's clock waits at each phase's end until the body goes on (body_hold): on time, however
    # late the body's process runs or the world answers
    assert result.duration == pytest.approx(planned, abs=PHASE_END_ROUNDING * len(phases))
    kinds = [(e["event"], e["tile"]) for e in sim.events if e["event"] in PLACEMENT_EVENTS]
    assert kinds == [("place_started", 1), ("placed", 1)]
    # the world shows the robot where it truly stands: beside the cache while it drives off with the tile
    snapshot = sim.call(seen[3][1][0])
    assert any(math.dist((p.x, p.y), phases[2].end) < 1e-6 for p in snapshot.robots), snapshot.robots
    assert math.dist(phases[2].end, cache) == pytest.approx(motion.approach_distance)
    assert list(snapshot.present_tiles) == []  # tile 1 goes down at the end of the placing phase
    after = sim.call(sim.snapshot.call_async(SimSnapshot.Request()))
    assert 1 in after.present_tiles
    assert any(math.dist((p.x, p.y), phases[-1].end) < 1e-6 for p in after.robots), after.robots


def test_a_placement_on_absent_supports_is_refused_naming_them(sim: Simulator) -> None:
    result = sim.place_tile(4)  # an octagon on tiles 1, 2, 3 and 6; only 1 is there
    assert result.error_code == PlaceTile.Result.FAILED_PRECONDITION
    assert list(result.missing_supports) == [2, 3, 6] and "support 2, 3, 6" in result.message
    assert sim.spin_until(lambda: any(e["event"] == "refused" and e["tile"] == 4 for e in sim.events), 10.0)
    assert sim.place_tile(99, like=1).error_code == PlaceTile.Result.FAILED_PRECONDITION


def test_kinect_frames_carry_the_time_of_the_world_they_show(sim: Simulator) -> None:
    assert sim.spin_until(lambda: len(sim.clouds) >= 2, 60.0), "no Kinect frames"
    cloud = sim.clouds[-1]
    assert (cloud.height, cloud.width, cloud.header.frame_id) == (480, 640, "camera_depth_optical_frame")
    stamps = {stamp_to_nanoseconds(p.header.stamp) for p in sim.vi_poses}
    assert stamp_to_nanoseconds(cloud.header.stamp) in stamps  # the overhead cameras saw the VI robot at that time
    judged = [e for e in sim.events if e["event"] in ("scan_judged", "scan_unjudged")]
    assert judged and all(e["event"] == "scan_unjudged" for e in judged)  # no vi_node here: nobody judges


def _process_tree(pid: int) -> list[int]:
    """`pid` and its descendants (a real `ros2 run` starts the node as its child)."""
    parents = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        parents.setdefault(int(fields[1]), []).append(int(stat.parent.name))
    tree, todo = [], [pid]
    while todo:
        tree.append(todo.pop())
        todo.extend(parents.get(tree[-1], []))
    return tree


def test_a_body_that_stalls_still_ends_each_phase_on_time(sim: Simulator) -> None:
    """A body's process that stops for 1 s of wall time mid-placement, as on a loaded host, still
    ends every phase on time: the world's clock waits for it. (Places tile 2: after the tests that
    count on it being absent.)"""
    before = sim.call(sim.snapshot.call_async(SimSnapshot.Request()))
    start = (before.robots[0].x, before.robots[0].y)  # robot1, the only assembly robot here
    stalled: list[int] = []

    def on_feedback(feedback: Any) -> None:
        if feedback.feedback.phase == PlaceTile.Feedback.DRIVING_TO_CACHE and not stalled:
            stalled.extend(_process_tree(sim.processes["sim_robot"].pid))
            for pid in stalled:
                os.kill(pid, signal.SIGSTOP)

    handle = sim.send_placement(2, on_feedback)
    result_future = handle.get_result_async()
    assert sim.spin_until(lambda: bool(stalled), 10.0), "no feedback from the body"
    sim.spin_until(lambda: False, 1.0)
    for pid in stalled:
        os.kill(pid, signal.SIGCONT)
    result = sim.call(result_future, timeout=60.0).result
    assert result.error_code == PlaceTile.Result.SUCCEEDED, result.message
    tile = PAPER.tiles[2]
    phases = placement_phases(RobotBodySettings().motion(), start, PAPER.caches[tile.type_name],
                              (tile.position[0], tile.position[1]),
                              [convex_hull_2d(t.vertices[:, :2]) for t in PAPER.tiles.values()])
    planned = sum(p.duration for p in phases)
    assert result.duration == pytest.approx(planned, abs=PHASE_END_ROUNDING * len(phases))


def test_a_goal_sent_before_the_world_is_found_waits_for_it() -> None:
    """A body serves its action at once (the team's clients find it early); the world may come later."""
    late = Simulator(world_later=True)
    try:
        late.wait_for_the_body()
        handle = late.send_placement(3)  # a floor tile
        result = handle.get_result_async()
        late.spin_until(result.done, 2.0)
        assert not result.done()  # no world, no answer, no time: the goal waits
        late.start_world()
        assert late.call(result, timeout=60.0).result.error_code == PlaceTile.Result.SUCCEEDED
    finally:
        late.close()


@pytest.mark.parametrize("executable", ["sim_world", "sim_robot", "sim_vi"])
def test_bad_parameters_give_one_line_and_exit_code_2(executable: str) -> None:
    # (a value of another type than the parameter file's does not override it: rcl keeps the file's)
    command = [*_command(executable, "/robot1"), "-p", "seed:=many"]
    result = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert lines == [f"{executable}: parameter 'seed' has the wrong type (got 'many', expected like 1)"]


def test_the_clock_waits_a_decision_window_for_the_robots_next_goal(sim: Simulator) -> None:
    """After a placement the world's clock stays at its end for `decision_window` (2 s of wall time in
    config/tiling_sim.yaml): the team's choice of the next goal costs no simulated time. Then it runs."""
    ticks: list[tuple[float, int]] = []  # (wall time, stamp)
    sim.node.create_subscription(ClockMsg, "/clock", lambda m: ticks.append((time.monotonic(),
                                                                               stamp_to_nanoseconds(m.clock))), 100)
    assert sim.place_tile(3).error_code == PlaceTile.Result.SUCCEEDED  # a floor tile
    done = time.monotonic()
    sim.spin_until(lambda: False, 3.0)
    held = {stamp for wall, stamp in ticks if done < wall < done + 1.4}
    later = [stamp for wall, stamp in ticks if wall > done + 2.5]
    assert len(held) == 1, sorted(held)
    assert later and min(later) > held.pop()


def test_a_vi_base_that_wakes_late_reports_the_arrival_the_world_was_told_of(sim: Simulator) -> None:
    """The VI robot's body stopped for 1 s of wall time while it drives (the world's clock runs on:
    nobody judges its frames here) wakes long after its arrival; the goal's final pose still carries
    the arrival it told the world, from which the explorer counts the frame the world holds for it
    (stamped with the body's wake-up, every viewpoint's frame looked too early to count)."""
    arrivals: list[float] = []
    sim.node.create_subscription(SimMotion, "/sim/motion",
                                 lambda m: arrivals.append(m.arrive_at) if m.robot == "vi" else None, SIM_MOTION)
    navigate = ActionClient(sim.node, NavigateTo, "/vi/navigate_to")
    assert sim.spin_until(navigate.server_is_ready, 30.0), "sim_vi never served navigate_to"
    goal = NavigateTo.Goal()
    goal.target.header.frame_id = "map"
    goal.target.pose.position.x, goal.target.pose.position.y = 0.9, 0.0
    goal.target.pose.orientation.z, goal.target.pose.orientation.w = 1.0, 0.0  # facing the structure
    stalled = _process_tree(sim.processes["sim_vi"].pid)
    handle = sim.call(navigate.send_goal_async(goal))
    assert handle.accepted
    for pid in stalled:
        os.kill(pid, signal.SIGSTOP)
    sim.spin_until(lambda: False, 1.0)
    for pid in stalled:
        os.kill(pid, signal.SIGCONT)
    result = sim.call(handle.get_result_async(), timeout=60.0).result
    assert result.success
    assert sim.spin_until(lambda: bool(arrivals), 5.0), "no motion on /sim/motion"
    assert stamp_to_nanoseconds(result.final_pose.header.stamp) == round(arrivals[-1] * 1e9)


def test_every_robot_is_seen_where_it_starts_when_simulated_time_starts() -> None:
    """The VI robot's explorer chooses its first viewpoint from its overhead pose while the world
    holds the clock at the start for it: the pose comes at the start, not with a first frame that
    the held clock never lets come (the explorer used to wait 10 s of wall time for it)."""
    bed = Simulator(world_arguments=("-p", "wait_for_start:=true"))
    try:
        start = bed.node.create_publisher(Empty, "/sim/start", SIM_EVENTS)
        assert bed.spin_until(lambda: start.get_subscription_count() > 0, 60.0), "sim_world never came up"
        bed.spin_until(lambda: False, DISCOVERY_SETTLING)
        assert not bed.vi_poses
        start.publish(Empty())
        assert bed.spin_until(lambda: bool(bed.vi_poses), 5.0), "no overhead pose of the VI robot at the start"
        assert stamp_to_nanoseconds(bed.vi_poses[0].header.stamp) == 0
        assert not bed.clouds  # the clock stays at its start: no frame yet
    finally:
        bed.close()


def test_a_robot_standing_at_a_cache_keeps_another_from_it_until_patience_runs_out() -> None:
    """robot2 (no body: it never moves) stands on the long rectangles' cache. robot1, sent for one,
    finds no other stop within reach of the cache, so it waits there `room_patience` s (60 s of
    simulated time in config/tiling_sim.yaml) and then goes in anyway, and the world says so."""
    cache = PAPER.caches["long_rectangle"]
    crowded = Simulator(world_arguments=("-p", f"robot_start_xy:=[{START[0]}, {START[1]}, {cache[0]}, {cache[1]}]"))
    try:
        crowded.wait_for_the_body()
        result = crowded.place_tile(1)
        assert result.error_code == PlaceTile.Result.SUCCEEDED, result.message
        motion = RobotBodySettings().motion()
        tile = PAPER.tiles[1]
        phases = placement_phases(motion, START, cache, (tile.position[0], tile.position[1]),
                                  [convex_hull_2d(t.vertices[:, :2]) for t in PAPER.tiles.values()])
        planned = sum(p.duration for p in phases)
        assert result.duration == pytest.approx(planned + 60.0, abs=0.01)
        waits = [e for e in crowded.events if e["event"] == "room_wait"]
        assert [(w["robot"], w["in_the_way"], w["seconds"], w["forced"]) for w in waits] == \
            [("robot1", ["robot2"], pytest.approx(60.0, abs=0.01), True)]
    finally:
        crowded.close()


def test_recorded_kinect_frames_replay_with_their_poses_and_the_truth(tmp_path: Path) -> None:
    """sim_vi with `record_scans` (experiment --record-scans): every frame, the overhead poses the
    team got and the truth go to a rosbag2 that `vi_node classify` reads, closed cleanly at Ctrl-C."""
    bag = tmp_path / "vi_scans"
    recording = Simulator(vi_arguments=("-p", f"record_scans:={bag}"))
    try:
        assert recording.spin_until(lambda: len(recording.clouds) >= 2, 60.0), "no Kinect frames"
    finally:
        outputs = recording.close()
    assert not any("ERROR" in output for output in outputs.values()), outputs
    replay = read_recording(bag)
    scans = list(replay.scans)
    truth = read_truth(bag)
    assert len(scans) >= 2 and len(truth["scans"]) == len(scans)
    assert all(scan.cloud is not None and scan.cloud.shape == (480, 640, 3) for scan in scans)
    for scan, told in zip(scans, truth["scans"], strict=True):
        assert told["stamp_ns"] == scan.stamp_ns and told["present"] == [] and told["robot"] == "vi"
        assert replay.poses.nearest(scan.stamp_ns, 100_000_000) is not None  # the overhead pose of that time
    assert len(told["pose"]) == 3 and told["robots"] and all(len(xy) == 2 for xy in told["robots"])
    assert truth["structure_file"].endswith("paper_14.yaml")


def test_a_recording_folder_that_exists_is_one_line_and_exit_code_2(tmp_path: Path) -> None:
    command = [*_command("sim_vi", "/vi"), "-p", f"record_scans:={tmp_path}"]
    result = subprocess.run(command, cwd=REPO, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stderr
    assert result.stderr.strip().splitlines() == [
        f"sim_vi: record_scans: {tmp_path} exists; a recording needs a new folder"]
