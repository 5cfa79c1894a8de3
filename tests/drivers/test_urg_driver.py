"""The URG driver (in this process) against the URG emulator (its own process, on a pty): the
SCIP 1.1 -> 2.0 switch, the baud search, PP geometry, scans of a tile, and faults survived."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from processes import Emulator
from test_create_driver import Events, wait_until

from hardware_drivers.planar_pose import Pose2D
from hardware_drivers.scip import URG_04LX
from hardware_drivers.tile_localization import find_tile
from hardware_drivers.urg_driver import UrgConfig, UrgDriver

TILE = Pose2D(0.3, 0.04, 0.5)
RECTANGLE = np.array([[-0.085, -0.02], [0.085, -0.02], [0.085, 0.02], [-0.085, 0.02]])


@pytest.fixture
def rig(tmp_path: Path):
    # an RS-232 URG-04LX in SCIP 1.1 at 19200 baud; the driver starts at 115200
    emulator = Emulator("urg", tmp_path / "urg", "--scip", "1.1", "--baud", "19200",
                        "--tile-pose", f"{TILE.x},{TILE.y},{TILE.yaw}", "--segments", "1.2,-3,1.2,3")
    events = Events()
    driver = UrgDriver(UrgConfig(port=str(tmp_path / "urg"), baud=115200), on_event=events)
    driver.start()
    assert driver.wait_connected(10.0), events.items
    wait_until(lambda: driver.latest_scan()[1] is not None, what="a first scan")
    yield emulator, driver, events
    driver.stop()
    emulator.close()


def test_connects_through_the_baud_search_and_the_scip_switch(rig) -> None:
    emulator, driver, events = rig
    events.wait_for("from SCIP 1.1 to SCIP 2.0")
    assert emulator.lines and any(text == "scip 2.0" for _, text in emulator.lines)
    assert driver.health.snapshot().values["baud"] == "19200"
    assert driver.parameters == URG_04LX
    assert "URG-04LX, 19200 baud, steps 44..725, 600 rpm" in events.wait_for("connected to the Hokuyo URG")


def test_scans_have_the_sensor_geometry_and_show_the_tile(rig) -> None:
    _, driver, _ = rig
    _, scan = driver.latest_scan()
    assert len(scan.ranges) == 725 - 44 + 1
    assert scan.angle_min == pytest.approx((44 - 384) * 2 * math.pi / 1024)
    assert scan.angle_max == pytest.approx((725 - 384) * 2 * math.pi / 1024)
    assert (scan.range_min, scan.range_max, scan.scan_time) == (0.02, 5.6, 0.1)
    front = scan.ranges[384 - 44]  # the beam on the front axis hits the tile's face
    assert 0.2 < front < 0.3
    assert np.isnan(scan.ranges).any()  # beams to the sides see nothing: error codes become NaN
    detection = find_tile(scan, RECTANGLE)
    assert detection is not None
    assert detection.pose.distance_to(TILE) < 0.01
    assert abs(math.remainder(detection.pose.yaw - TILE.yaw, math.pi)) < math.radians(5)


def test_a_scan_with_a_bad_line_is_dropped_and_counted(rig) -> None:
    emulator, driver, events = rig
    emulator.send("corrupt 2")
    events.wait_for("URG scan dropped: checksum error")
    wait_until(lambda: driver.health.counter("corrupt_scans") >= 2, what="two corrupt scans counted")
    scans = driver.health.counter("scans")
    wait_until(lambda: driver.health.counter("scans") > scans + 2, what="valid scans after")
    assert driver.health.counter("disconnects") == 0


def test_partial_scans_and_garbage_are_dropped(rig) -> None:
    emulator, driver, _ = rig
    emulator.send("partial")
    emulator.send("garbage 150")
    wait_until(lambda: driver.health.counter("corrupt_scans") >= 1, what="the damaged scan counted")
    scans = driver.health.counter("scans")
    wait_until(lambda: driver.health.counter("scans") > scans + 2, what="valid scans after")


def test_a_hardware_fault_reconnects_after_the_error_limit(rig) -> None:
    emulator, driver, events = rig
    emulator.send("fault 55")
    events.wait_for("URG reports hardware fault (status 55)", 3.0)
    events.wait_for("4 bad scans in a row", 3.0)
    emulator.send("fault 0")
    wait_until(lambda: driver.health.counter("connects") >= 2, 5.0, "the reconnect")
    scans = driver.health.counter("scans")
    wait_until(lambda: driver.health.counter("scans") > scans, what="scans after the reconnect")


def test_an_unplugged_sensor_is_reconnected(rig) -> None:
    emulator, driver, events = rig
    emulator.send("unplug 0.8")
    events.wait_for("Hokuyo URG lost", 3.0)
    wait_until(lambda: driver.health.counter("connects") >= 2, 8.0, "the reconnect")


def test_silence_is_a_lost_sensor(rig) -> None:
    emulator, driver, events = rig
    emulator.send("silence 1.5")
    events.wait_for("no scan for 1 s", 3.0)
    wait_until(lambda: driver.health.counter("connects") >= 2, 8.0, "the reconnect")


def test_no_reply_at_any_baud_is_named(tmp_path: Path) -> None:
    events = Events()
    emulator = Emulator("urg", tmp_path / "urg", "--baud", "57600")  # a rate the driver does not try
    driver = UrgDriver(UrgConfig(port=str(tmp_path / "urg"), baud=115200, reply_timeout=0.2), on_event=events)
    driver.start()
    try:
        message = events.wait_for("no SCIP reply", 5.0)
        assert "at 115200, 19200, 38400 baud: is the URG connected and powered?" in message
    finally:
        driver.stop()
        emulator.close()
