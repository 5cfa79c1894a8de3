"""The M3 robot's remove_tile action against the three device emulators, every part a real process
(the rig of `m3_rig`, as test_m3_robot.py): a long rectangle lies on the structure shifted and
turned from where tile 3 should be; the robot finds it with the laser, lifts it and leaves it at the
drop-off. One goal at a time across place_tile and remove_tile: the robot has one arm."""

from __future__ import annotations

import math
import re
import time
from typing import Any

import pytest
from m3_rig import m3_rig
from processes import wheels_stop
from rclpy.action import ActionClient
from ros_probe import probe_health, shared_probe, wait_for_future

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.remove_tile_mission import RemovalPhase
from tiling_assembly_msgs.action import PlaceTile, RemoveTile

pytestmark = pytest.mark.ros

START = (0.0, -0.45, 1.2)  # the base's true pose at power-up (m, m, rad)
BELIEVED = (0.0, 0.0, 0.0, 0.0)  # tile 3 of paper_14: x, y, z, yaw
TILE_ON_STRUCTURE = (0.03, -0.02, 0.5)  # where the tile really lies (x, y, yaw): 3.6 cm and 29 deg off
DROP_OFF = (0.3, -0.5)
FAR = (1.5, 1.5)  # a goal this far keeps the robot driving


@pytest.fixture(scope="module")
def m3(tmp_path_factory: pytest.TempPathFactory):
    with m3_rig(tmp_path_factory.mktemp("m3_remove"), START, TILE_ON_STRUCTURE) as rig:
        clients = [ActionClient(shared_probe().node, RemoveTile, "/robot1/remove_tile"),
                   ActionClient(shared_probe().node, PlaceTile, "/robot1/place_tile")]
        try:
            for client in clients:
                assert client.wait_for_server(timeout_sec=30.0), f"{client._action_name} server did not come up"
            yield {**rig, "m3_robot": rig["nodes"]["m3_robot"], "remove": clients[0], "place": clients[1]}
        finally:
            for client in clients:
                shared_probe().retire(client)


def _removal(tile_type: str = "long_rectangle", at: tuple[float, float] = BELIEVED[:2]) -> RemoveTile.Goal:
    goal = RemoveTile.Goal(tile_id=3, tile_type=tile_type)
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x, goal.pose.pose.position.y = at
    goal.pose.pose.position.z = BELIEVED[2]
    goal.pose.pose.orientation.z, goal.pose.pose.orientation.w = math.sin(BELIEVED[3] / 2), math.cos(BELIEVED[3] / 2)
    goal.drop_off.x, goal.drop_off.y = DROP_OFF
    return goal


def _placement(cache: tuple[float, float]) -> PlaceTile.Goal:
    goal = PlaceTile.Goal(tile_id=3, tile_type="long_rectangle")
    goal.pose.header.frame_id = "map"
    goal.cache.x, goal.cache.y = cache
    return goal


def _send(client: ActionClient, goal: Any, feedback: list | None = None) -> Any:
    """The goal's handle; sent again when no response came (a goal response can be lost; the
    server frees a goal that never started after its grace, see GoalSlot)."""
    for _attempt in range(3):
        on_feedback = None if feedback is None else (lambda f: feedback.append(f.feedback))
        sent = client.send_goal_async(goal, feedback_callback=on_feedback)
        deadline = time.monotonic() + 8.0
        while not sent.done() and time.monotonic() < deadline:
            time.sleep(0.02)
        if sent.done():
            return sent.result()
    raise AssertionError(f"goal not answered in three attempts ({probe_health()})")


def _wait_for(condition, timeout: float, what: str) -> None:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"{what} did not come within {timeout} s ({probe_health()})"
        time.sleep(0.02)


def test_remove_tile_finds_the_shifted_tile_and_leaves_it_at_the_drop_off(m3) -> None:
    feedback: list[RemoveTile.Feedback] = []
    handle = _send(m3["remove"], _removal(), feedback)
    assert handle.accepted
    result = wait_for_future(handle.get_result_async(), 90.0, "the removal").result
    assert result.error_code == RemoveTile.Result.SUCCEEDED, result.message
    assert result.message == ""
    phases = [f.phase for f in feedback]
    assert [p for i, p in enumerate(phases) if i == 0 or phases[i - 1] != p] == list(RemovalPhase)
    # found where it really lies, not where it was believed to be
    found = result.found_pose
    assert found.header.frame_id == "map"
    assert math.hypot(found.pose.position.x - TILE_ON_STRUCTURE[0], found.pose.position.y - TILE_ON_STRUCTURE[1]) < 0.01
    found_yaw = 2 * math.atan2(found.pose.orientation.z, found.pose.orientation.w)
    assert abs(math.remainder(found_yaw - TILE_ON_STRUCTURE[2], math.pi)) < math.radians(5)
    assert result.duration > 0
    deviation = re.search(r"tile 3 lies ([\d.]+) cm and (\d+) deg from its believed pose", m3["m3_robot"].log())
    assert deviation, m3["m3_robot"].log()
    assert abs(float(deviation[1]) - 3.6) < 1.0 and abs(float(deviation[2]) - 29) <= 5
    # the gripper closed on it, and the robot left it at the drop-off and backed away
    assert any(text.startswith(f"goal 6 {dx.radians_to_position(-0.6)}") for _, text in m3["arm"].lines)
    x, y, _ = m3["create"].true_pose()
    assert 0.32 < math.hypot(x - DROP_OFF[0], y - DROP_OFF[1]) < 0.32 + 0.10 + 0.05
    assert wheels_stop(m3["create"], within=2.0)


@pytest.mark.parametrize(("running", "refused"), [("remove", "place"), ("place", "remove")])
def test_one_goal_at_a_time_across_remove_tile_and_place_tile(m3, running: str, refused: str) -> None:
    goals = {"remove": _removal(at=FAR), "place": _placement(FAR)}
    feedback: list = []
    handle = _send(m3[running], goals[running], feedback)
    assert handle.accepted
    _wait_for(lambda: bool(feedback) and feedback[-1].phase_progress > 0.05, 20.0, "the base driving")
    assert not _send(m3[refused], goals[refused]).accepted
    handle.cancel_goal_async()
    result = wait_for_future(handle.get_result_async(), 20.0, "the canceled goal").result
    assert (result.error_code, result.message) == (type(result).CANCELED, "canceled")
    assert wheels_stop(m3["create"], within=2.0)
    noun = {"remove": "removal", "place": "placement"}
    assert f"{refused}_tile goal for tile 3 rejected: tile 3's {noun[running]} is under way" in m3["m3_robot"].log()


def test_a_removal_of_an_unknown_tile_type_fails_with_one_line(m3) -> None:
    handle = _send(m3["remove"], _removal(tile_type="hexagon"))
    assert handle.accepted
    result = wait_for_future(handle.get_result_async(), 10.0, "the removal").result
    assert result.error_code == RemoveTile.Result.FAILED_NOT_FOUND
    assert result.message == "unknown tile type 'hexagon' (no footprint from /structure or structure_file)"
