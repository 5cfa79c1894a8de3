"""vi_node as a real ROS 2 process: recorded scans replayed from another process, S_a from the
team's topics, and bad input over the middleware."""

from __future__ import annotations

import json
import math
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import stop_node_process
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PoseStamped
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from ros_helpers.isolated_domains import fresh_domain
from rosbags.rosbag2 import Reader
from sensor_msgs.msg import PointCloud2, PointField
from vi_helpers import REPO, SCANS, STRUCTURES, ros2_command, ros2_run, structure
from visualization_msgs.msg import MarkerArray

from tiling_assembly.messages import structure_to_msg
from tiling_assembly_msgs.msg import AuctionAnnouncement, PlacementReport, RobotStatus, TileStateArray
from tiling_sim.inspection_scenarios import Scene, ViewSettings, robots_beside, view_from
from tiling_sim.kinect import KinectSimulator
from tiling_sim.scan_bag import ScanBagWriter, read_truth

pytestmark = pytest.mark.ros

PAPER = str(STRUCTURES / "paper_14.yaml")
STATE_NAMES = {1: "present", 2: "missing", 3: "occluded", 4: "misplaced"}


@contextmanager
def vi_node(probe: Probe, *params: str) -> Iterator[subprocess.Popen[str]]:
    args = [ros2_command(), "run", "vi_node", "vi_node", "--ros-args", "-r", "__ns:=/vi"]
    for p in params:
        args += ["-p", p]
    process = subprocess.Popen(args, cwd=REPO, env=probe.domain.environ(), stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    try:
        yield process
    finally:
        stop_node_process(process)


class Probe:
    """A node of the test: records what vi_node publishes, publishes what the team would."""

    def __init__(self) -> None:
        self.domain = fresh_domain()
        self.context = self.domain.context
        self.node = Node("vi_probe", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.states: list[TileStateArray] = []
        self.markers: list[MarkerArray] = []
        self.diagnostics: list[str] = []
        self.node.create_subscription(TileStateArray, "/tile_states", self.states.append, 10)
        self.node.create_subscription(MarkerArray, "/tile_markers", self.markers.append, 10)
        self.node.create_subscription(
            DiagnosticArray,
            "/diagnostics",
            lambda m: self.diagnostics.extend(s.message for s in m.status),
            50,
        )
        reliable = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.cloud = self.node.create_publisher(PointCloud2, "/vi/camera/depth/points", reliable)
        self.pose = self.node.create_publisher(PoseStamped, "/vi/overhead_pose", reliable)
        latched = QoSProfile(
            depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
        )
        from tiling_assembly_msgs.msg import Structure

        self.structure = self.node.create_publisher(Structure, "/structure", latched)
        self.reports = self.node.create_publisher(PlacementReport, "/placement_reports", 100)
        self.auctions = self.node.create_publisher(AuctionAnnouncement, "/auction/announcements", 50)

    def spin_until(self, done: Callable[[], bool], timeout: float) -> bool:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if done():
                return True
            self.executor.spin_once(timeout_sec=0.05)
        return done()

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()


@pytest.fixture
def probe() -> Iterator[Probe]:
    p = Probe()
    yield p
    p.close()


def offline(bag: str, *args: str) -> list[dict[str, Any]]:
    result = ros2_run("vi_node", "classify", "--structure", PAPER, "--bag", bag, *args)
    assert result.returncode == 0, result.stderr
    return [json.loads(line) for line in result.stdout.splitlines()]


def replay(probe: Probe, bag: str, pacing: tuple[str, ...] = ("--rate", "0", "--gap", "1.0")) -> (
        subprocess.CompletedProcess[str]):
    return subprocess.run(
        [
            ros2_command(),
            "run",
            "tiling_sim",
            "replay_bag",
            "--bag",
            bag,
            *pacing,
            "--wait-subscribers",
            "20",
            "--start-delay",
            "1.5",
        ],
        cwd=REPO,
        env=probe.domain.environ(),
        capture_output=True,
        text=True,
        timeout=60,
    )


def test_replayed_scans_give_the_same_states_as_the_offline_command(probe: Probe) -> None:
    bag = str(SCANS / "paper_vga")
    truth = read_truth(bag)
    with vi_node(probe, f"structure_file:={PAPER}", "mode:=paper", "fuse_scans:=false") as node:
        assert probe.spin_until(lambda: probe.node.count_publishers("/tile_states") > 0, 30), (
            "vi_node did not start"
        )
        replayed = replay(probe, bag)
        assert replayed.returncode == 0, replayed.stderr
        assert "published 4 messages" in replayed.stdout
        assert probe.spin_until(lambda: len(probe.states) >= 2, 30), probe.diagnostics
        assert node.poll() is None
    expected = offline(bag, "--mode", "paper", "--no-fuse")
    assert len(probe.states) == 2
    for msg, line, scan in zip(probe.states, expected, truth["scans"], strict=True):
        assert msg.header.stamp.sec + msg.header.stamp.nanosec / 1e9 == pytest.approx(scan["stamp_ns"] / 1e9)
        assert msg.header.frame_id == "map" and msg.scan_count == 1
        got = {
            str(s.tile_id): (STATE_NAMES[s.state], s.physical_support, s.virtual_support) for s in msg.states
        }
        assert got == {k: (v["state"], v["physical"], v["virtual"]) for k, v in line["tiles"].items()}
        assert got["10"][0] == got["13"][0] == "missing"
        camera = scan["view"]["camera"]
        assert (
            abs(msg.camera_pose.position.x - camera[0][3]) < 0.02
            and abs(msg.camera_pose.position.y - camera[1][3]) < 0.02
        )
        assert 0 < msg.alignment_rms < 0.01
    markers = {m.id: m for m in probe.markers[-1].markers if m.action == m.ADD}
    assert sorted(markers) == list(range(1, 15))
    assert markers[13].color.r > 0.8 and markers[13].color.g < 0.2  # missing: red
    assert markers[11].color.g > 0.7 and markers[11].color.r < 0.2  # present: green
    assert any(m.startswith("classified 14 tiles") for m in probe.diagnostics)


def test_default_mode_over_ros_fuses_scans_and_reports_the_misplaced_tile(probe: Probe) -> None:
    bag = str(SCANS / "paper_misplaced_qvga")
    truth = read_truth(bag)
    moved = truth["misplaced"][0]
    with vi_node(probe, f"structure_file:={PAPER}") as node:  # the defaults: default mode, fused
        assert probe.spin_until(lambda: probe.node.count_publishers("/tile_states") > 0, 30), (
            "vi_node did not start"
        )
        result = replay(probe, bag)
        assert result.returncode == 0, result.stderr
        assert probe.spin_until(lambda: len(probe.states) >= 2, 30), probe.diagnostics
        assert node.poll() is None
    expected = offline(bag)
    assert [m.scan_count for m in probe.states] == [1, 2]
    for msg, line in zip(probe.states, expected, strict=True):
        got = {
            str(s.tile_id): (
                STATE_NAMES[s.state],
                s.physical_support,
                s.virtual_support,
                s.see_through_support,
            )
            for s in msg.states
        }
        assert got == {
            k: (v["state"], v["physical"], v["virtual"], v.get("see_through", 0))
            for k, v in line["tiles"].items()
        }
    final = {s.tile_id: s for s in probe.states[-1].states}
    assert (
        final[moved].state == 4
        and abs(final[moved].offset_yaw - truth["misplaced_pose"][str(moved)]["yaw"]) < 0.05
    )
    assert final[13].state == 2 and final[13].scan_count == 2
    measured = [m for m in probe.markers[-1].markers if m.ns == "measured"]
    assert [m.id for m in measured] == [moved]


def bag_messages(name: str) -> list[tuple[str, Any]]:
    out = []
    with Reader(SCANS / name) as reader:
        for connection, _, raw in reader.messages():
            kind = PointCloud2 if connection.topic.endswith("points") else PoseStamped
            out.append((connection.topic, deserialize_message(bytes(raw), kind)))
    return out


def test_bad_input_and_the_expected_structure_over_ros(probe: Probe) -> None:
    messages = bag_messages("paper_qvga")
    pose, cloud = messages[2][1], messages[3][1]  # the second view of the recording
    paper = structure()
    with vi_node(probe, "mode:=paper", "sensor_reliability:=reliable", "min_support:=20") as node:
        assert probe.spin_until(lambda: probe.node.count_subscribers("/vi/camera/depth/points") > 0, 30)
        time.sleep(0.5)

        def send(scan: PointCloud2, wait_for: Callable[[], bool]) -> None:
            probe.pose.publish(pose)
            time.sleep(0.05)
            probe.cloud.publish(scan)
            assert probe.spin_until(wait_for, 20), probe.diagnostics

        # no structure yet: the scan is dropped with a diagnostic
        send(cloud, lambda: any("no structure yet" in m for m in probe.diagnostics))
        probe.structure.publish(structure_to_msg(paper))
        for tile in (1, 2, 3, 4, 5, 6, 7, 12):
            probe.reports.publish(
                PlacementReport(tile_id=tile, outcome=PlacementReport.OUTCOME_PLACED, robot_name="robot1")
            )
        probe.spin_until(lambda: False, 1.0)

        nan_cloud = deserialize_message(bytes(_serialize(cloud)), PointCloud2)
        nan_cloud.data = bytes(b"\xff\xff\xc0\x7f" * (len(cloud.data) // 4))  # every coordinate NaN
        send(nan_cloud, lambda: any("no valid points" in m for m in probe.diagnostics))
        wrong_frame = deserialize_message(bytes(_serialize(cloud)), PointCloud2)
        wrong_frame.header.frame_id = "base_link"
        send(wrong_frame, lambda: any("frame 'base_link'" in m for m in probe.diagnostics))
        no_z = deserialize_message(bytes(_serialize(cloud)), PointCloud2)
        no_z.fields = [
            PointField(name="x", offset=0, datatype=7, count=1),
            PointField(name="y", offset=4, datatype=7, count=1),
        ]
        send(no_z, lambda: any("no z field" in m for m in probe.diagnostics))
        # every bad scan is answered with no states and why (the simulated camera waits for answers)
        assert all(not m.states and m.problem for m in probe.states), probe.states
        assert any("no z field" in m.problem for m in probe.states)
        probe.states.clear()

        send(cloud, lambda: len(probe.states) == 1)
        assert probe.states[0].problem == ""
        assert sorted(s.tile_id for s in probe.states[0].states) == [1, 2, 3, 4, 5, 6, 7, 12]
        announcement = AuctionAnnouncement(tile_id=12, reason=AuctionAnnouncement.REASON_MISSING)
        announcement.header.stamp.sec = 50
        probe.auctions.publish(announcement)
        probe.spin_until(lambda: False, 0.5)
        send(cloud, lambda: len(probe.states) == 2)
        assert sorted(s.tile_id for s in probe.states[1].states) == [1, 2, 3, 4, 5, 6, 7]
        replaced = PlacementReport(tile_id=12, outcome=PlacementReport.OUTCOME_PLACED, robot_name="robot2")
        replaced.header.stamp.sec = 60
        probe.reports.publish(replaced)
        probe.spin_until(lambda: False, 0.5)
        send(cloud, lambda: len(probe.states) == 3)
        assert 12 in [s.tile_id for s in probe.states[2].states]
        # a repair: the wrong tile still lies there (and hides what it hid) until it is reported taken off
        repair = AuctionAnnouncement(tile_id=12, reason=AuctionAnnouncement.REASON_MISPLACED)
        repair.header.stamp.sec = 70
        probe.auctions.publish(repair)
        probe.spin_until(lambda: False, 0.5)
        send(cloud, lambda: len(probe.states) == 4)
        assert 12 in [s.tile_id for s in probe.states[3].states]
        taken_off = PlacementReport(tile_id=12, outcome=PlacementReport.OUTCOME_REMOVED, robot_name="robot2")
        taken_off.header.stamp.sec = 80
        probe.reports.publish(taken_off)
        probe.spin_until(lambda: False, 0.5)
        send(cloud, lambda: len(probe.states) == 5)
        assert 12 not in [s.tile_id for s in probe.states[4].states]
        assert node.poll() is None


def _serialize(msg: Any) -> bytes:
    from rclpy.serialization import serialize_message

    return serialize_message(msg)


@pytest.mark.parametrize(
    "param, text",
    [
        ("mode:=clever", "parameter 'mode' must be one of"),
        ("structure_file:=/nonexistent.yaml", "structure_file:"),
        ("camera_xyz:=[1.0, 2.0]", "camera_xyz"),
    ],
)
def test_bad_parameters_stop_the_node_with_one_line(param: str, text: str) -> None:
    result = subprocess.run(
        [ros2_command(), "run", "vi_node", "vi_node", "--ros-args", "-p", param],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert result.returncode != 0
    lines = [line for line in result.stderr.strip().splitlines() if line]
    assert len(lines) == 1 and text in lines[0] and "Traceback" not in result.stderr


def record_scene_with_robots(
    path: Path, robots_after: int = 0
) -> tuple[tuple[int, ...], list[tuple[float, float, float]]]:
    """Two scans of the paper structure with tile 14 gone and two robots standing beside it,
    their overhead poses recorded as the overhead cameras publish them (`robots_after` ns after the
    scan: the other robots' poses come on their own topics, in no order with the scan)."""
    paper = structure()
    rng = np.random.default_rng(41)
    scene = Scene(paper, tuple(paper.tile_ids), (14,))
    scene.robots = robots_beside(paper, scene.expected, rng, 2)
    settings = replace(ViewSettings(), errors_at_bound=True)
    simulator = KinectSimulator(seed=41)
    with ScanBagWriter(path) as bag:
        for k, bearing in enumerate((120.0, 200.0)):
            view = view_from(scene.centre, math.radians(bearing), 1.1, rng, settings, scene.robots)
            stamp = (100 + k) * 10**9
            bag.write_pose(stamp - 5_000_000, *view.overhead)
            for n, robot in enumerate(view.robots):
                bag.write_pose(stamp - 5_000_000 + robots_after, *robot, robot=f"robot{n + 1}")
            bag.write_scan(stamp, simulator.scan(scene.kinect_scene, view.camera))
    return scene.removed, list(view.robots)


def test_other_robots_overhead_poses_are_followed_and_their_points_left_out(probe: Probe, tmp_path: Path) -> None:
    bag = tmp_path / "robots"
    removed, _ = record_scene_with_robots(bag)
    offline_states = offline(str(bag))
    assert all("error" not in line for line in offline_states)
    assert offline_states[-1]["tiles"]["14"]["state"] == "missing"
    assert all(v["state"] != "missing" for k, v in offline_states[-1]["tiles"].items() if int(k) not in removed)
    with vi_node(probe, f"structure_file:={PAPER}", "other_robots:=robot1,robot2") as node:
        assert probe.spin_until(lambda: probe.node.count_publishers("/tile_states") > 0, 30), "vi_node did not start"
        result = replay(probe, str(bag))
        assert result.returncode == 0, result.stderr
        assert probe.spin_until(lambda: len(probe.states) >= 2, 30), probe.diagnostics
        assert node.poll() is None
    assert any("(2 other robots in the scene)" in m for m in probe.diagnostics), probe.diagnostics
    states = {s.tile_id: STATE_NAMES[s.state] for s in probe.states[-1].states}
    assert states == {int(k): v["state"] for k, v in offline_states[-1]["tiles"].items()}


def test_a_scan_waits_for_the_other_robots_poses_of_its_moment(probe: Probe, tmp_path: Path) -> None:
    """The robots' poses come 0.1 s after the scan they belong to (as the simulator's can, when the
    executor takes the scan first): vi_node waits for them and leaves both robots out."""
    bag = tmp_path / "robots_late"
    record_scene_with_robots(bag, robots_after=100_000_000)
    with vi_node(probe, f"structure_file:={PAPER}", "other_robots:=robot1,robot2") as node:
        assert probe.spin_until(lambda: probe.node.count_publishers("/tile_states") > 0, 30), "vi_node did not start"
        result = replay(probe, str(bag), pacing=("--rate", "1"))  # as recorded: the poses 0.1 s late
        assert result.returncode == 0, result.stderr
        assert probe.spin_until(lambda: len(probe.states) >= 2, 30), probe.diagnostics
        assert node.poll() is None
    classified = [m for m in probe.diagnostics if m.startswith("classified")]
    assert classified and all("(2 other robots in the scene)" in m for m in classified), probe.diagnostics


def test_scans_are_inspected_while_the_simulated_clock_stands_still(probe: Probe) -> None:
    """The simulator stops its clock while the scan the explorer waits for is rendered: vi_node
    inspects a scan on arrival when its overhead pose is there, and on wall time when the pose
    comes after it, whatever the simulated clock does (here: no /clock at all)."""
    messages = bag_messages("paper_qvga")
    pose, cloud = messages[2][1], messages[3][1]
    with vi_node(probe, f"structure_file:={PAPER}", "use_sim_time:=true", "sensor_reliability:=reliable") as node:
        assert probe.spin_until(lambda: probe.node.count_subscribers("/vi/camera/depth/points") > 0, 30)
        time.sleep(0.5)
        probe.pose.publish(pose)
        time.sleep(0.1)
        probe.cloud.publish(cloud)
        assert probe.spin_until(lambda: len(probe.states) == 1, 20), probe.diagnostics
        later = deserialize_message(bytes(_serialize(cloud)), PointCloud2)
        later.header.stamp.sec += 2
        later_pose = deserialize_message(bytes(_serialize(pose)), PoseStamped)
        later_pose.header.stamp.sec += 2
        probe.cloud.publish(later)
        time.sleep(0.05)
        probe.pose.publish(later_pose)
        assert probe.spin_until(lambda: len(probe.states) == 2, 20), probe.diagnostics
        assert [m.problem for m in probe.states] == ["", ""]
        assert node.poll() is None


def test_a_camera_that_comes_up_later_is_read_as_it_is_offered_before_the_simulated_clock_runs(
        probe: Probe) -> None:
    """`auto` reliability follows the publishers on the steady clock: on the simulated one (not yet
    running at a trial's start) the reliable Kinect stream stayed on a best-effort reader, which
    loses fragmented clouds, and the trial's first scan was lost."""
    camera = "/vi_late/camera/depth/points"

    def readers() -> list[ReliabilityPolicy]:
        return [i.qos_profile.reliability for i in probe.node.get_subscriptions_info_by_topic(camera)]

    args = [ros2_command(), "run", "vi_node", "vi_node", "--ros-args", "-r", "__ns:=/vi_late",
            "-p", f"structure_file:={PAPER}", "-p", "use_sim_time:=true"]
    process = subprocess.Popen(args, cwd=REPO, env=probe.domain.environ(), stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    try:
        assert probe.spin_until(lambda: readers() == [ReliabilityPolicy.BEST_EFFORT], 30), readers()
        probe.node.create_publisher(PointCloud2, camera, QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE))
        assert probe.spin_until(lambda: readers() == [ReliabilityPolicy.RELIABLE], 10), readers()
    finally:
        stop_node_process(process)


def record_one_scan(path: Path, scene: Scene, bearing: float) -> Path:
    """A bag of one scan of `scene` at 100 s from `bearing` (rad), 1 m away, with its overhead pose."""
    view = view_from(scene.centre, bearing, 1.0, np.random.default_rng(5))
    with ScanBagWriter(path) as writer:
        writer.write_pose(100 * 10**9 - 5_000_000, *view.overhead)
        writer.write_scan(100 * 10**9, KinectSimulator(seed=6).scan(scene.kinect_scene, view.camera))
    return path


def states_after_replay(probe: Probe, node: subprocess.Popen[str], bag: Path) -> dict[int, str | None]:
    """Replay `bag` to the running vi_node once S_a has settled; the states of its last answer."""
    probe.spin_until(lambda: False, 1.0)
    result = replay(probe, str(bag))
    assert result.returncode == 0, result.stderr
    assert probe.spin_until(lambda: len(probe.states) >= 1, 30), probe.diagnostics
    assert node.poll() is None
    return {s.tile_id: STATE_NAMES.get(s.state) for s in probe.states[-1].states}


def test_a_tile_a_robot_is_placing_is_expected_not_judged(probe: Probe, tmp_path: Path) -> None:
    """Square 10 lies on the structure before its robot reports it placed. Offline, without the
    team's statuses, its points make rectangle 11 look like a tile of the wrong type; vi_node hears
    the robot placing 10 on /robot_status and says nothing of either."""
    paper = structure()
    scene = Scene(paper, tuple(paper.tile_ids), ())
    bag = record_one_scan(tmp_path / "unreported", scene, bearing=0.0)
    reported = [t for t in paper.tile_ids if t != 10]
    offline_states = offline(str(bag), "--expected", ",".join(map(str, reported)))
    assert offline_states[0]["tiles"]["11"]["state"] == "misplaced"

    placing = RobotStatus(robot_name="robot1", state=RobotStatus.PLACING, current_tile=10)
    placing.header.stamp.sec = 98
    status = probe.node.create_publisher(RobotStatus, "/robot_status", 10)
    probe.node.create_timer(0.2, lambda: status.publish(placing))
    with vi_node(probe, "sensor_reliability:=reliable") as node:
        assert probe.spin_until(lambda: probe.node.count_subscribers("/robot_status") > 0, 30), "vi_node did not start"
        probe.structure.publish(structure_to_msg(paper))
        for tile in reported:
            probe.reports.publish(PlacementReport(tile_id=tile, outcome=PlacementReport.OUTCOME_PLACED,
                                                  robot_name="robot1"))
        states = states_after_replay(probe, node, bag)
    assert sorted(states) == reported
    assert "misplaced" not in states.values(), states


def test_a_tile_reported_placed_after_the_scan_was_taken_is_not_judged_by_it(probe: Probe, tmp_path: Path) -> None:
    """Square 10 lands just after the scan; its report (stamped later) reaches vi_node before the
    scan is judged. Judged against S_a with 10 in it, the scan says 10 is missing; a scan taken
    before a report does not judge the tile it reports."""
    paper = structure()
    scene = Scene(paper, tuple(paper.tile_ids), (10,))
    bag = record_one_scan(tmp_path / "before_the_report", scene, bearing=math.radians(90.0))
    assert offline(str(bag))[0]["tiles"]["10"]["state"] == "missing"

    with vi_node(probe, "sensor_reliability:=reliable") as node:
        assert probe.spin_until(lambda: probe.node.count_subscribers("/placement_reports") > 0, 30), "no vi_node"
        probe.structure.publish(structure_to_msg(paper))
        for tile in paper.tile_ids:
            report = PlacementReport(tile_id=tile, outcome=PlacementReport.OUTCOME_PLACED, robot_name="robot1")
            report.header.stamp.sec = 101 if tile == 10 else 50
            probe.reports.publish(report)
        states = states_after_replay(probe, node, bag)
    assert sorted(states) == [t for t in paper.tile_ids if t != 10]
    assert "missing" not in states.values(), states
