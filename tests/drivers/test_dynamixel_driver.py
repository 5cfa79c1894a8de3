"""The arm driver (in this process) against the Dynamixel emulator (its own process, on a pty):
pings, goals reached at the set speed, limits, joint errors, and serial faults survived."""

from __future__ import annotations

import time
from pathlib import Path

import pytest
from processes import Emulator
from test_create_driver import Events, wait_until

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.device_health import Level
from hardware_drivers.dynamixel_driver import (
    ArmConfig,
    ArmDriver,
    JointConfig,
    JointGoalError,
    joint_went_silent,
)

NAMES = ("base_yaw", "shoulder", "elbow", "wrist_pitch", "wrist_roll", "gripper")


def joints() -> tuple[JointConfig, ...]:
    # the shoulder is mounted mirrored with an offset, as servos on a real arm often are
    mirrored = {"shoulder"}
    return tuple(
        JointConfig(name, i + 1, offset=0.2 if name in mirrored else 0.0,
                    direction=-1 if name in mirrored else 1, lower=-1.5, upper=1.5, max_velocity=2.0)
        for i, name in enumerate(NAMES)
    )


@pytest.fixture
def rig(tmp_path: Path):
    emulator = Emulator("dynamixel", tmp_path / "arm", "--stall", f"6:{dx.radians_to_position(-0.3)}")
    events = Events()
    driver = ArmDriver(ArmConfig(port=str(tmp_path / "arm"), joints=joints()), on_event=events)
    driver.start()
    assert driver.wait_connected(5.0), events.items
    events.wait_for("6 of 6 joints answer")
    wait_until(lambda: len(positions(driver)) == 6, what="first readings")
    yield emulator, driver, events
    driver.stop()
    emulator.close()


def positions(driver: ArmDriver) -> dict[str, float]:
    return {n: r.position for n, r in driver.readings()[1].items()}


def test_a_goal_is_reached_at_the_planned_speed_and_reported(rig) -> None:
    emulator, driver, _ = rig
    before = positions(driver)
    assert before["shoulder"] == pytest.approx(0.2, abs=0.01)  # the servo at its centre
    speeds = driver.set_goals({"shoulder": 0.8, "elbow": -0.4}, duration=1.0)
    assert speeds["shoulder"] == pytest.approx(0.6, abs=0.02)
    assert speeds["elbow"] == pytest.approx(0.4, abs=0.02)
    # the shoulder servo is mirrored: its goal is -0.8 + 0.2 rad
    line = emulator.wait_for("goal 2 ", 2.0)
    assert int(line.split()[2]) == dx.radians_to_position(-0.6)
    start = time.monotonic()
    def arrived() -> bool:
        now = positions(driver)
        return abs(now["shoulder"] - 0.8) < 0.02 and abs(now["elbow"] + 0.4) < 0.02

    wait_until(arrived, 5.0, "the goal")
    assert time.monotonic() - start > 0.5  # moved at the set speed, not at once
    reading = driver.readings()[1]["shoulder"]
    assert reading.voltage == 12.0 and reading.temperature == 35.0 and reading.errors == ()


def test_goals_outside_the_limits_or_for_unknown_joints_are_refused(rig) -> None:
    _, driver, _ = rig
    with pytest.raises(JointGoalError, match=r"goal 1.700 rad for joint elbow is outside its limits"):
        driver.set_goals({"elbow": 1.7})
    with pytest.raises(JointGoalError, match="unknown joint 'knee'"):
        driver.set_goals({"knee": 0.0})


def test_the_gripper_stops_on_an_object(rig) -> None:
    _, driver, _ = rig
    driver.set_goals({"gripper": -1.2})
    def closed() -> bool:
        return not driver.readings()[1]["gripper"].moving and positions(driver)["gripper"] < -0.2

    wait_until(closed, 5.0, "the gripper closing")
    assert positions(driver)["gripper"] == pytest.approx(-0.3, abs=0.01)
    assert driver.readings()[1]["gripper"].load < -0.3  # squeezing


def test_a_joint_error_is_reported_and_torque_can_be_re_enabled(rig) -> None:
    emulator, driver, events = rig
    emulator.send("error 3 overload")
    events.wait_for("joint elbow (id 3) reports: overload")
    wait_until(lambda: driver.health.level == Level.ERROR, what="the error level")
    assert "elbow: overload" in driver.health.snapshot().message
    assert driver.joint_errors() == {"elbow": ("overload",)}
    ok, message = driver.set_torque(True)
    assert not ok and "elbow keeps torque off (overload)" in message  # the cause is still there
    emulator.send("error 3 none")
    events.wait_for("joint elbow (id 3): error cleared")
    assert driver.set_torque(True) == (True, "torque enabled on 6 joints")
    emulator.wait_for("torque 3 1", 2.0)


def test_a_silent_joint_is_retried_reported_and_recovered(rig) -> None:
    emulator, driver, events = rig
    emulator.send("mute 4 on")
    events.wait_for("joint wrist_pitch (id 4) stopped answering "
                    "(3 reads in a row over 0.5 s, 3 tries of 30 ms per read)")
    assert "wrist_pitch" not in driver.readings()[1]
    assert driver.connected  # the other joints go on
    assert driver.health.counter("silent_transactions") >= 1
    emulator.send("mute 4 off")
    events.wait_for("joint wrist_pitch (id 4) answers again")


def test_a_short_stall_of_the_bus_is_no_silence(rig) -> None:
    emulator, driver, events = rig
    emulator.send("silence 0.25")  # a busy host, a burst of noise: a read or two of each joint missed
    emulator.wait_for("silence")
    wait_until(lambda: driver.health.counter("silent_transactions") >= 1, what="missed reads")
    sequence = driver.readings()[0]
    wait_until(lambda: driver.readings()[0] > sequence + 3, what="readings after the stall")
    assert not [m for _, m in events.items if "stopped answering" in m]
    assert len(positions(driver)) == 6


def test_a_joint_is_silent_after_reads_in_a_row_and_time_without_a_reply() -> None:
    config = ArmConfig(port="/dev/null", joints=joints())
    assert not joint_went_silent(1, 2.0, config)  # one read missed in a cycle a slow host stretched
    assert not joint_went_silent(2, 0.9, config)
    assert not joint_went_silent(5, 0.3, config)  # many quick reads in a row, little time
    assert joint_went_silent(3, 0.6, config)


def test_corrupt_replies_and_garbage_are_retried(rig) -> None:
    emulator, driver, _ = rig
    emulator.send("corrupt 4")
    emulator.send("garbage 100")
    wait_until(lambda: driver.health.counter("corrupt_packets") >= 4, what="corrupt replies counted")
    sequence = driver.readings()[0]
    wait_until(lambda: driver.readings()[0] > sequence + 3, what="readings after the damage")
    assert driver.health.counter("disconnects") == 0
    assert not driver.health.snapshot().message.startswith("joint faults")


def test_an_unplugged_bus_is_reconnected(rig) -> None:
    emulator, driver, events = rig
    emulator.send("unplug 0.8")
    events.wait_for("CrustCrawler arm lost", 3.0)
    wait_until(lambda: driver.health.counter("connects") >= 2, 5.0, "the reconnect")
    wait_until(lambda: len(positions(driver)) == 6, what="readings after the reconnect")


def lossy_rig(tmp_path: Path, *emulator_args: str):  # type: ignore[no-untyped-def]
    emulator = Emulator("dynamixel", tmp_path / "arm", *emulator_args)
    events = Events()
    driver = ArmDriver(ArmConfig(port=str(tmp_path / "arm"), joints=joints()), on_event=events)
    return emulator, driver, events


def reach(driver: ArmDriver, goals: dict[str, float], timeout: float = 5.0) -> None:
    driver.set_goals(goals, duration=0.3)
    wait_until(lambda: all(abs(positions(driver).get(n, 9.0) - v) < 0.02 for n, v in goals.items()),
               timeout, f"the goal {goals}")


def test_goal_writes_the_servos_miss_are_sent_again(tmp_path: Path) -> None:
    emulator, driver, events = lossy_rig(tmp_path, "--drop-goals", "0.3", "--seed", "5")
    driver.start()
    try:
        assert driver.wait_connected(5.0), events.items
        for target in (0.8, -0.6, 0.3):
            reach(driver, dict.fromkeys(NAMES, target))
        missed = [text for _, text in emulator.lines if text.startswith("missed ") and text.endswith(" goal")]
        assert missed, "the emulator dropped no goal write: the test proves nothing"
        assert driver.health.counter("goals_resent") >= 1
        events.wait_for("missed its goal")
        assert driver.health.level != Level.ERROR
    finally:
        driver.stop()
        emulator.close()


def test_a_joint_whose_configuration_was_lost_at_connect_is_configured_later(tmp_path: Path) -> None:
    emulator, driver, events = lossy_rig(tmp_path, "--seed", "2")
    driver.start()
    try:
        # a noisy bus from the first joint's torque on: some later joint loses a configuration step
        emulator.wait_for("torque 1 1", 5.0)
        emulator.send("packet-loss 0.6")
        assert driver.wait_connected(5.0), events.items
        emulator.send("packet-loss 0")
        emulator.wait_for("packet-loss 0", 2.0)
        assert driver.health.counter("configure_failures") >= 1, "every configuration went through"
        events.wait_for("configured, torque on")
        wait_until(lambda: all(f"torque {i} 1" in [t for _, t in emulator.lines] for i in range(1, 7)),
                   what="torque on every servo")
        reach(driver, dict.fromkeys(NAMES, 0.5))
    finally:
        driver.stop()
        emulator.close()


def test_a_servo_silent_at_connect_is_configured_when_it_answers(tmp_path: Path) -> None:
    emulator, driver, events = lossy_rig(tmp_path)
    emulator.send("mute 3 on")
    emulator.wait_for("mute 3 on")
    driver.start()
    try:
        events.wait_for("5 of 6 joints answer")
        emulator.send("mute 3 off")
        events.wait_for("joint elbow (id 3) configured, torque on")
        emulator.wait_for("torque 3 1", 2.0)
        reach(driver, {"elbow": -1.0})
    finally:
        driver.stop()
        emulator.close()


def test_a_lossy_bus_still_brings_every_joint_to_its_goals(tmp_path: Path) -> None:
    emulator, driver, events = lossy_rig(tmp_path, "--packet-loss", "0.15", "--seed", "3")
    driver.start()
    try:
        assert driver.wait_connected(5.0), events.items
        for target in (-0.7, 0.9):
            reach(driver, dict.fromkeys(NAMES, target))
        assert not [m for _, m in events.items if "stopped answering" in m]  # a lost read is no silence
        assert driver.health.counter("failed_attempts") >= 1
        assert driver.health.level != Level.ERROR
    finally:
        driver.stop()
        emulator.close()


def test_no_servo_answering_is_named(tmp_path: Path) -> None:
    emulator = Emulator("dynamixel", tmp_path / "arm", "--ids", "11,12")
    events = Events()
    driver = ArmDriver(ArmConfig(port=str(tmp_path / "arm"), joints=joints(), reply_timeout=0.01, retries=2),
                       on_event=events)
    driver.start()
    try:
        message = events.wait_for("no servo answers a ping", 5.0)
        assert "is the arm powered, and the baud rate 1000000 right?" in message
    finally:
        driver.stop()
        emulator.close()


def test_bad_joint_configuration_is_refused() -> None:
    with pytest.raises(ValueError, match="servo ids repeat"):
        ArmConfig(port="/dev/null", joints=(JointConfig("a", 1), JointConfig("b", 1))).validate()
    with pytest.raises(ValueError, match="maps outside the servo"):
        ArmConfig(port="/dev/null", joints=(JointConfig("a", 1, offset=2.0, upper=1.0),)).validate()
