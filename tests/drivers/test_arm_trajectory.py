"""The arm node runs a trajectory's points one after the other even when the arm lags behind their
times: a point the joints' speed limits cannot reach in time is finished before the next one is
sent, not cut short (the arm node and the Dynamixel emulator as real processes)."""

from __future__ import annotations

import time

import pytest
from processes import Emulator, NodeProcess
from ros_probe import shared_probe
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from hardware_drivers import dynamixel_protocol as dx

pytestmark = pytest.mark.ros

NAMESPACE = "/trajectory_test"


@pytest.fixture(scope="module")
def arm(tmp_path_factory: pytest.TempPathFactory):
    directory = tmp_path_factory.mktemp("trajectory")
    emulator = Emulator("dynamixel", directory / "arm")
    # a generous wait for a lagging point: on a loaded machine the driver's readings come late, and a
    # point given up on would look like a cut corner
    node = NodeProcess("crustcrawler_arm", directory, "-p", f"port:={directory / 'arm'}",
                       "-p", "trajectory_wait:=8.0", namespace=NAMESPACE,
                       params_files=("config/hardware_drivers.yaml", "config/crustcrawler_arm.yaml"))
    try:
        joints = shared_probe().collect(JointState, f"{NAMESPACE}/joint_states")
        node.wait_for_log("connected to the", timeout=20.0)
        yield joints, emulator
    finally:
        node.stop()
        emulator.close()
    assert "Traceback" not in node.log(), node.log()


def point(shoulder: float, seconds: float) -> JointTrajectoryPoint:
    result = JointTrajectoryPoint()
    result.positions = [shoulder]
    result.time_from_start.sec = int(seconds)
    result.time_from_start.nanosec = round((seconds - int(seconds)) * 1e9)
    return result


def shoulder_at(angle: float):  # type: ignore[no-untyped-def]
    def matches(message: JointState) -> bool:
        return abs(dict(zip(message.name, message.position, strict=False))["shoulder"] - angle) < 0.02

    return matches


def test_a_point_the_arm_reaches_late_is_finished_before_the_next(arm) -> None:
    arm, emulator = arm
    arm.wait_for(lambda m: "shoulder" in m.name, 10.0, "joint states")
    trajectory = JointTrajectory()
    trajectory.joint_names = ["shoulder"]
    # 1.0 rad in 0.2 s needs 5 rad/s; the shoulder's limit (crustcrawler_arm.yaml) is 1 rad/s
    trajectory.points = [point(1.0, 0.2), point(0.5, 0.4)]
    arm.clear()
    publisher = shared_probe().publisher(JointTrajectory, f"{NAMESPACE}/joint_trajectory", wait_for_subscriber=10.0)
    publisher.publish(trajectory)
    # the emulator says where the servo was when each goal came: the joint states, sampled at 20 Hz,
    # can miss the moment the arm turns
    first_goal = int(emulator.wait_for("goal 2 ", 10.0).split()[2])
    second = emulator.wait_for("goal 2 ", 20.0).split()
    assert abs(int(second[5]) - first_goal) * dx.RAD_PER_POSITION <= 0.02, second
    arm.wait_for(shoulder_at(0.5), 10.0, "the second point", after=time.monotonic())
