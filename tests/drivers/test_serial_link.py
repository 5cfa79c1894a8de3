"""Port ownership shared by the three drivers: one-line reasons for unusable ports, and every
driver waiting for a port that is missing at start."""

from __future__ import annotations

from pathlib import Path

import pytest
from processes import Emulator
from test_create_driver import Events

from hardware_drivers.create_driver import CreateConfig, CreateDriver
from hardware_drivers.dynamixel_driver import ArmConfig, ArmDriver, JointConfig
from hardware_drivers.serial_link import DeviceUnavailableError, SerialPort
from hardware_drivers.urg_driver import UrgConfig, UrgDriver


def test_unusable_ports_are_named_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(DeviceUnavailableError, match=r"nothing does not exist \(device unplugged or off\?\)"):
        SerialPort(str(tmp_path / "nothing"), 57600).open()
    (tmp_path / "file").write_text("not a tty")
    with pytest.raises(DeviceUnavailableError, match=r"cannot open .*/file: "):
        SerialPort(str(tmp_path / "file"), 57600).open()
    emulator = Emulator("create", tmp_path / "create")
    try:
        first = SerialPort(str(tmp_path / "create"), 57600)
        first.open()
        with pytest.raises(DeviceUnavailableError, match=r"cannot open .*/create: .*lock"):
            SerialPort(str(tmp_path / "create"), 57600).open()  # one owner per port
        first.close()
    finally:
        emulator.close()


DRIVERS = {
    "create": lambda port, events: CreateDriver(CreateConfig(port=port), events),
    "dynamixel": lambda port, events: ArmDriver(ArmConfig(port=port, joints=(JointConfig("j1", 1),)), events),
    "urg": lambda port, events: UrgDriver(UrgConfig(port=port, baud=19200), events),
}


@pytest.mark.parametrize("kind", sorted(DRIVERS))
def test_every_driver_waits_for_a_port_missing_at_start(kind: str, tmp_path: Path) -> None:
    port = tmp_path / kind
    events = Events()
    driver = DRIVERS[kind](str(port), events)
    driver.start()
    try:
        message = events.wait_for("does not exist", 3.0)
        assert message.endswith("retrying every 0.5 s") and "\n" not in message
        emulator = Emulator(kind, port)
        try:
            assert driver.wait_connected(10.0), events.items
            assert driver.health.snapshot().values["connected"] == "true"
        finally:
            emulator.close()
    finally:
        driver.stop()
