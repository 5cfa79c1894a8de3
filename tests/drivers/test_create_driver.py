"""The Create driver (in this process) against the Create emulator (its own process, on a pty):
odometry, wheel limits, watchdog, hazards, and every serial fault survived and reported."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest
from processes import Emulator

from hardware_drivers.create_driver import CreateConfig, CreateDriver
from hardware_drivers.device_health import Level


class Events:
    def __init__(self) -> None:
        self.items: list[tuple[Level, str]] = []

    def __call__(self, level: Level, message: str) -> None:
        self.items.append((level, message))

    def wait_for(self, text: str, timeout: float = 5.0) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for _, message in self.items:
                if text in message:
                    return message
            time.sleep(0.02)
        raise AssertionError(f"no event containing '{text}' within {timeout} s; events: {self.items}")


def wait_until(condition, timeout: float = 5.0, what: str = "the condition") -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, f"{what} did not happen within {timeout} s"
        time.sleep(0.02)


def drive_for(driver: CreateDriver, linear: float, angular: float, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        driver.drive(linear, angular)
        time.sleep(0.05)


@pytest.fixture
def rig(tmp_path: Path):
    emulator = Emulator("create", tmp_path / "create")
    events = Events()
    driver = CreateDriver(CreateConfig(port=str(tmp_path / "create")), on_event=events)
    driver.start()
    assert driver.wait_connected(5.0), events.items
    yield emulator, driver, events
    driver.stop()
    emulator.close()


def test_odometry_follows_the_emulated_base(rig) -> None:
    emulator, driver, _ = rig
    drive_for(driver, 0.25, 0.8, 1.5)
    drive_for(driver, 0.0, 0.0, 0.3)
    x, y, yaw = emulator.true_pose()
    _, state = driver.state()
    assert math.hypot(state.pose.x - x, state.pose.y - y) < 0.005
    assert abs(math.remainder(state.pose.yaw - yaw, 2 * math.pi)) < math.radians(1.5)
    assert math.hypot(x, y) > 0.2  # it really moved
    assert state.voltage == pytest.approx(15.8) and state.charge == pytest.approx(2.5)


def test_commands_are_clamped_and_the_watchdog_stops_the_wheels(rig) -> None:
    emulator, driver, events = rig
    right, left = driver.drive(5.0, 0.0)  # far beyond the limits
    assert right == left == pytest.approx(0.3)  # max_linear
    right, left = driver.drive(0.3, 2.0)  # the turn pushes one wheel past 0.5 m/s: both scale down
    assert max(right, left) == pytest.approx(0.5) and right > left
    sent_at = time.monotonic()
    emulator.wait_for("drive 500", 2.0)
    stop = emulator.wait_for("drive 0 0", 2.0)
    stopped_after = float(stop.split("t=")[1]) - sent_at
    assert stopped_after >= 0.15  # not before the watchdog's 0.2 s
    events.wait_for("no velocity command for 0.2 s: wheels stopped")
    assert driver.health.counter("watchdog_stops") >= 1


def test_a_bump_stops_the_wheels_and_allows_only_backing_away(rig) -> None:
    emulator, driver, events = rig
    driver.drive(0.2, 0.0)
    emulator.wait_for("drive 200 200")
    emulator.send("bump left")
    emulator.wait_for("drive 0 0", 2.0)
    events.wait_for("wheels stopped: left bumper")
    assert driver.health.level == Level.ERROR
    assert driver.drive(0.2, 0.0) == (0.0, 0.0)  # forward refused while pressed
    assert driver.drive(-0.1, 0.0) == pytest.approx((-0.1, -0.1))
    emulator.wait_for("drive -100 -100")
    emulator.send("bump none")
    events.wait_for("driving allowed again")
    assert driver.drive(0.1, 0.0) == pytest.approx((0.1, 0.1))


def test_a_wheel_drop_stops_the_wheels(rig) -> None:
    emulator, driver, events = rig
    driver.drive(0.2, 0.0)
    emulator.wait_for("drive 200 200")
    emulator.send("drop right")
    emulator.wait_for("drive 0 0", 2.0)
    events.wait_for("wheels stopped: right wheel dropped")
    assert driver.drive(-0.1, 0.0) == (0.0, 0.0)
    emulator.send("drop none")


def test_garbage_partial_and_corrupt_frames_are_counted_and_skipped(rig) -> None:
    emulator, driver, _ = rig
    emulator.send("garbage 200")
    emulator.send("partial")
    emulator.send("corrupt 3")
    wait_until(lambda: driver.health.counter("corrupt_frames") >= 3, what="corrupt frames counted")
    sequence, _ = driver.state()
    wait_until(lambda: driver.state()[0] > sequence + 10, what="valid frames after the damage")
    assert driver.connected
    assert driver.health.counter("discarded_bytes") >= 200
    assert driver.health.counter("disconnects") == 0


def test_a_silent_robot_is_reported_and_reconnected(rig) -> None:
    emulator, driver, events = rig
    emulator.send("silence 1.0")
    events.wait_for("no valid sensor frame for 0.5 s (robot off or asleep?)", 3.0)
    wait_until(lambda: driver.health.counter("connects") >= 2, 5.0, "a reconnect")
    assert driver.connected


def test_an_unplugged_robot_is_reported_and_reconnected(rig) -> None:
    emulator, driver, events = rig
    emulator.send("unplug 1.0")
    events.wait_for("iRobot Create lost: device on", 3.0)
    events.wait_for("does not exist (device unplugged or off?)", 3.0)
    assert not driver.connected
    assert driver.health.snapshot().values["connected"] == "false"
    emulator.wait_for("ready", 3.0)
    wait_until(lambda: driver.connected, 5.0, "the reconnect")
    sequence, _ = driver.state()
    wait_until(lambda: driver.state()[0] > sequence, what="new frames")


def test_a_missing_port_at_start_is_retried_until_the_robot_appears(tmp_path: Path) -> None:
    events = Events()
    driver = CreateDriver(CreateConfig(port=str(tmp_path / "create")), on_event=events)
    driver.start()
    try:
        events.wait_for(f"port {tmp_path / 'create'} does not exist", 3.0)
        time.sleep(1.2)  # several retries: still one message
        assert sum("does not exist" in m for _, m in events.items) == 1
        assert driver.health.counter("connect_failures") >= 2
        emulator = Emulator("create", tmp_path / "create")
        try:
            assert driver.wait_connected(5.0)
        finally:
            emulator.close()
    finally:
        driver.stop()


def test_a_wrong_baud_rate_is_named(tmp_path: Path) -> None:
    emulator = Emulator("create", tmp_path / "create", "--baud", "115200")  # a Create 2
    events = Events()
    driver = CreateDriver(CreateConfig(port=str(tmp_path / "create"), baud=57600), on_event=events)
    driver.start()
    try:
        message = events.wait_for("no sensor stream", 5.0)
        assert "the baud rate 57600 right (Create 1: 57600, Create 2: 115200)?" in message
        assert not driver.connected
    finally:
        driver.stop()
        emulator.close()


def test_create2_encoder_odometry_across_the_counter_wrap(tmp_path: Path) -> None:
    emulator = Emulator("create", tmp_path / "create", "--model", "create2", "--baud", "115200")
    driver = CreateDriver(CreateConfig(port=str(tmp_path / "create"), baud=115200, model="create2",
                                       odometry="encoders"))
    driver.start()
    try:
        assert driver.wait_connected(5.0)
        drive_for(driver, 0.3, 0.0, 1.0)  # ~0.3 m: the emulator's counters start 236 counts before the wrap
        drive_for(driver, 0.0, 0.0, 0.3)
        x, y, _ = emulator.true_pose()
        _, state = driver.state()
        assert x > 0.2
        assert math.hypot(state.pose.x - x, state.pose.y - y) < 0.005
    finally:
        driver.stop()
        emulator.close()


def test_bad_configuration_is_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match="odometry 'encoders' needs model 'create2'"):
        CreateDriver(CreateConfig(port="/dev/null", odometry="encoders"))
