"""The M3 robot's place_tile action against the three device emulators, every part a real process.

The Create emulator writes its true pose to a file; the URG emulator renders the scene (a long
rectangle lying at its parts cache) from that pose, so the laser sees the tile from wherever the
base has driven; the Dynamixel emulator's gripper servo stops on the tile when it closes. The test
stands in for the overhead cameras: it publishes the true pose on overhead_pose.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable

import pytest
from m3_rig import GRIPPER_ON_TILE, m3_rig
from processes import wheels_stop
from rclpy.action import ActionClient
from ros_probe import probe_health, shared_probe

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.place_tile_mission import Outcome, Phase
from tiling_assembly_msgs.action import NavigateTo, PlaceTile

pytestmark = pytest.mark.ros

START = (0.0, -0.45, 0.3)  # the base's true pose at power-up (m, m, rad)
CACHE = (0.0, -1.0)  # long_rectangle cache of paper_14
TILE_AT_CACHE = (0.02, -1.01, 0.4)  # where the tile really lies (x, y, yaw)
GOAL = (0.0, 0.0, 0.0, 0.0)  # tile 3 of paper_14: x, y, z, yaw


@pytest.fixture(scope="module")
def m3(tmp_path_factory: pytest.TempPathFactory):
    with m3_rig(tmp_path_factory.mktemp("m3"), START, TILE_AT_CACHE) as rig:
        client = ActionClient(shared_probe().node, PlaceTile, "/robot1/place_tile")
        try:
            assert client.wait_for_server(timeout_sec=30.0), "place_tile server did not come up"
            yield {**rig, "client": client}
        finally:
            shared_probe().retire(client)


def _goal(tile_id: int = 3) -> PlaceTile.Goal:
    goal = PlaceTile.Goal()
    goal.tile_id = tile_id
    goal.tile_type = "long_rectangle"
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x, goal.pose.pose.position.y, goal.pose.pose.position.z = GOAL[:3]
    goal.pose.pose.orientation.z, goal.pose.pose.orientation.w = math.sin(GOAL[3] / 2), math.cos(GOAL[3] / 2)
    goal.cache.x, goal.cache.y = CACHE
    return goal


def _send(client: ActionClient, goal: PlaceTile.Goal, feedback: list):  # type: ignore[no-untyped-def]
    """Send the goal; send it again when no response came (a goal response can be lost, as over
    WiFi; the server frees a goal that never started after its grace, see GoalSlot)."""
    for _attempt in range(3):
        sent = client.send_goal_async(goal, feedback_callback=lambda f: feedback.append(f.feedback))
        deadline = time.monotonic() + 8.0
        while not sent.done() and time.monotonic() < deadline:
            time.sleep(0.02)
        if sent.done():
            return sent.result()
    raise AssertionError(f"goal not accepted in three attempts ({probe_health()})")


def _run_goal(client: ActionClient, goal: PlaceTile.Goal, timeout: float,
              cancel_in_phase: int | None = None,
              on_phase: tuple[int, Callable[[], None]] | None = None,
              ) -> tuple[PlaceTile.Result, list, float | None]:
    feedback: list[PlaceTile.Feedback] = []
    handle = _send(client, goal, feedback)
    assert handle.accepted
    result_future = handle.get_result_async()
    deadline = time.monotonic() + timeout
    canceled_at = None
    while not result_future.done():
        assert time.monotonic() < deadline, f"no result within {timeout} s; last phases {feedback[-3:]}"
        latest = feedback[-1] if feedback else None
        if on_phase is not None and latest is not None and latest.phase == on_phase[0]:
            on_phase[1]()
            on_phase = None
        if cancel_in_phase is not None and canceled_at is None and latest is not None \
                and latest.phase == cancel_in_phase and latest.phase_progress > 0.1:
            canceled_at = time.monotonic()
            handle.cancel_goal_async()
        time.sleep(0.02)
    return result_future.result().result, feedback, canceled_at


def test_place_tile_completes_against_the_emulators(m3) -> None:
    result, feedback, _ = _run_goal(m3["client"], _goal(), timeout=120.0)
    assert result.error_code == PlaceTile.Result.SUCCEEDED, result.message
    assert result.message == ""
    phases = [f.phase for f in feedback]
    order = [p for i, p in enumerate(phases) if i == 0 or phases[i - 1] != p]
    assert order == [Phase.DRIVING_TO_CACHE, Phase.LOCATING_TILE, Phase.PICKING, Phase.DRIVING_TO_STRUCTURE,
                     Phase.PLACING, Phase.RETREATING]
    placed = result.placed_pose.pose
    assert result.placed_pose.header.frame_id == "map"
    assert math.hypot(placed.position.x - GOAL[0], placed.position.y - GOAL[1]) < 0.02
    assert abs(placed.position.z - GOAL[2]) < 0.01
    placed_yaw = 2 * math.atan2(placed.orientation.z, placed.orientation.w)
    # a long rectangle looks the same turned by pi
    assert abs(math.remainder(placed_yaw - GOAL[3], math.pi)) < math.radians(5)
    assert result.duration > 0
    # the laser found the tile where it really lies, within 1 cm
    log = m3["nodes"]["m3_robot"].log()
    found = re.search(r"found the long_rectangle at \(([-\d.]+) m, ([-\d.]+) m, ([-\d.]+) deg\)", log)
    assert found, log
    x, y, yaw = (float(v) for v in found.groups())
    assert math.hypot(x - TILE_AT_CACHE[0], y - TILE_AT_CACHE[1]) < 0.01
    assert abs(math.remainder(math.radians(yaw) - TILE_AT_CACHE[2], math.pi)) < math.radians(5)
    # the gripper closed on the tile, and the wheels are stopped at the end
    assert any(text.startswith(f"goal 6 {dx.radians_to_position(-0.6)}") for _, text in m3["arm"].lines)
    assert wheels_stop(m3["create"], within=2.0), [t for _, t in m3["create"].lines if t.startswith("drive ")][-3:]


def test_no_tile_at_the_cache_fails_with_no_tile(m3) -> None:
    m3["urg"].send("tile none")
    m3["urg"].wait_for("tile none")
    try:
        result, feedback, _ = _run_goal(m3["client"], _goal(), timeout=60.0)
    finally:
        m3["urg"].send("tile " + ",".join(str(v) for v in TILE_AT_CACHE))
    assert result.error_code == PlaceTile.Result.FAILED_NO_TILE
    assert "no long_rectangle found by the laser near its cache" in result.message
    assert "\n" not in result.message
    assert feedback[-1].phase == Phase.LOCATING_TILE
    assert Outcome.FAILED_NO_TILE == PlaceTile.Result.FAILED_NO_TILE


def test_a_laser_that_reconnects_while_the_tile_is_located_does_not_fail_the_placement(m3) -> None:
    """The laser falls silent as the mission starts looking: hokuyo_urg drops the connection after
    its scan_timeout and reconnects; the mission waits for the scans to come back."""
    reconnects_before = m3["nodes"]["hokuyo_urg"].log().count("connected to the")
    result, feedback, _ = _run_goal(m3["client"], _goal(), timeout=120.0,
                                    on_phase=(Phase.LOCATING_TILE, lambda: m3["urg"].send("silence 2.5")))
    assert result.error_code == PlaceTile.Result.SUCCEEDED, result.message
    m3["nodes"]["hokuyo_urg"].wait_for_log("connected to the", timeout=10.0, count=reconnects_before + 1)
    assert Phase.PICKING in [f.phase for f in feedback]


def test_a_gripper_closing_on_nothing_fails_with_grasp_error(m3) -> None:
    m3["arm"].send("stall 6 none")  # no tile between the fingers
    m3["arm"].wait_for("stall 6 none")
    try:
        result, feedback, _ = _run_goal(m3["client"], _goal(), timeout=60.0)
    finally:
        m3["arm"].send(f"stall 6 {GRIPPER_ON_TILE}")
    assert result.error_code == PlaceTile.Result.FAILED_GRASP
    assert result.message == "the gripper closed on nothing: the tile was not grasped"
    assert feedback[-1].phase == Phase.PICKING


def test_cancel_stops_the_wheels(m3) -> None:
    goal = _goal()
    goal.cache.x, goal.cache.y = 1.5, 1.5  # far away: the cancel comes while driving
    m3["create"].drain()
    result, _, canceled_at = _run_goal(m3["client"], goal, timeout=60.0,
                                              cancel_in_phase=Phase.DRIVING_TO_CACHE)
    assert canceled_at is not None
    assert result.error_code == PlaceTile.Result.CANCELED
    assert result.message == "canceled"
    drives = [(float(text.split("t=")[1]), text) for _, text in m3["create"].lines
              if text.startswith("drive ")]
    before = [text for t, text in drives if t < canceled_at]
    assert before and not before[-1].startswith("drive 0 0"), "the base was not moving when the cancel came"
    after = [(t, text) for t, text in drives if t >= canceled_at]
    assert after and after[-1][1].startswith("drive 0 0"), "the wheels were left turning after the cancel"
    assert after[-1][0] - canceled_at < 2.0


def test_the_same_goal_sent_again_follows_the_placement_under_way(m3) -> None:
    placements_before = m3["nodes"]["m3_robot"].log().count("placing tile 3 ")
    goal = _goal()
    goal.cache.x, goal.cache.y = 1.5, 1.5  # far away: the placement is still driving
    feedback: list = []
    first = _send(m3["client"], goal, feedback)
    assert first.accepted
    _wait_until(lambda: bool(feedback), 20.0, "feedback from the placement")
    # what a client does that missed the goal response: the same goal again
    again = _send(m3["client"], goal, [])
    assert again.accepted
    assert not _send(m3["client"], _goal(tile_id=4), []).accepted  # another tile: refused meanwhile
    again.cancel_goal_async()  # the follower's cancel ends the one placement
    results = [_wait(handle.get_result_async(), 20.0).result for handle in (first, again)]
    assert [r.error_code for r in results] == [PlaceTile.Result.CANCELED] * 2
    assert m3["nodes"]["m3_robot"].log().count("placing tile 3 ") == placements_before + 1
    assert wheels_stop(m3["create"], within=2.0)


def _wait_until(condition, timeout: float, what: str) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"{what} did not come within {timeout} s"
        time.sleep(0.02)


def _wait(future, timeout: float):  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not future.done():
        assert time.monotonic() < deadline, f"no result within {timeout} s"
        time.sleep(0.02)
    return future.result()


def test_a_device_that_stops_answering_fails_with_hardware_error(m3) -> None:
    m3["arm"].send("unplug 0")
    m3["nodes"]["crustcrawler_arm"].wait_for_log("CrustCrawler arm lost", timeout=10.0)
    try:
        result, _, _ = _run_goal(m3["client"], _goal(), timeout=30.0)
    finally:
        m3["arm"].send("plug")
    assert result.error_code == PlaceTile.Result.FAILED_HARDWARE
    assert result.message.startswith("crustcrawler_arm")
    m3["nodes"]["crustcrawler_arm"].wait_for_log("connected to the CrustCrawler arm", timeout=10.0, count=2)


def test_navigate_to_drives_the_base_home_and_is_refused_while_a_placement_runs(m3, tmp_path) -> None:
    """The assembly robot going home with nothing left to place (assembly_node's parking)."""
    navigate = ActionClient(shared_probe().node, NavigateTo, "/robot1/navigate_to")
    try:
        assert navigate.wait_for_server(timeout_sec=20.0)
        home = NavigateTo.Goal()
        home.target.header.frame_id = "map"
        home.target.pose.position.x, home.target.pose.position.y = 0.4, -0.7
        home.target.pose.orientation.z, home.target.pose.orientation.w = math.sin(0.6), math.cos(0.6)  # 1.2 rad
        # one base: refused while a placement drives it
        placing = _goal()
        placing.cache.x, placing.cache.y = 1.5, 1.5
        feedback: list = []
        first = _send(m3["client"], placing, feedback)
        _wait_until(lambda: bool(feedback), 20.0, "feedback from the placement")
        refused = _wait(navigate.send_goal_async(home), 10.0)
        assert not refused.accepted
        first.cancel_goal_async()
        assert _wait(first.get_result_async(), 20.0).result.error_code == PlaceTile.Result.CANCELED
        drive_feedback: list = []
        handle = None
        deadline = time.monotonic() + 15.0
        while handle is None or not handle.accepted:  # the slot frees once the placement has ended
            assert time.monotonic() < deadline, "navigate_to refused after the placement ended"
            handle = _wait(navigate.send_goal_async(
                home, feedback_callback=lambda f: drive_feedback.append(f.feedback)), 10.0)
            time.sleep(0.2)
        result = _wait(handle.get_result_async(), 90.0).result
    finally:
        shared_probe().retire(navigate)
    assert result.success, result.message
    final = result.final_pose.pose
    assert math.hypot(final.position.x - 0.4, final.position.y + 0.7) < 0.03
    x, y, yaw = (float(v) for v in m3["pose_file"].read_text().split()[:3])
    assert math.hypot(x - 0.4, y + 0.7) < 0.05, (x, y)  # the base itself, not just its belief
    assert abs(math.remainder(yaw - 1.2, math.tau)) < math.radians(10), yaw
    assert drive_feedback and drive_feedback[0].distance_remaining > drive_feedback[-1].distance_remaining
    assert wheels_stop(m3["create"], within=2.0)
