"""The Dynamixel Protocol 1.0 codec and AX-12 units, against the Robotis manual's examples."""

from __future__ import annotations

import math

import pytest

from hardware_drivers import dynamixel_protocol as dx
from hardware_drivers.dynamixel_protocol import AX12, ErrorBit, Instruction


def test_packets_match_the_manual_examples() -> None:
    assert dx.ping(1) == bytes.fromhex("ff ff 01 02 01 fb")
    # READ the internal temperature of servo 1, and its status packet (32 degC)
    assert dx.read(1, AX12.PRESENT_TEMPERATURE, 1) == bytes.fromhex("ff ff 01 04 02 2b 01 cc")
    assert dx.status_packet(1, 0, bytes([32])) == bytes.fromhex("ff ff 01 03 00 20 db")
    # broadcast WRITE of ID 1
    assert dx.write(dx.BROADCAST_ID, AX12.ID, bytes([1])) == bytes.fromhex("ff ff fe 04 03 03 01 f6")
    # SYNC_WRITE goal position and speed to servos 0..3
    blocks = {0: bytes.fromhex("10 00 50 01"), 1: bytes.fromhex("20 02 60 03"),
              2: bytes.fromhex("30 00 70 01"), 3: bytes.fromhex("20 02 80 03")}
    assert dx.sync_write(AX12.GOAL_POSITION, blocks) == bytes.fromhex(
        "ff ff fe 18 83 1e 04 00 10 00 50 01 01 20 02 60 03 02 30 00 70 01 03 20 02 80 03 12")


def test_parser_resynchronises_and_counts_bad_checksums() -> None:
    parser = dx.PacketParser()
    good = dx.status_packet(3, ErrorBit.OVERLOAD, bytes([1, 2]))
    bad = bytearray(dx.status_packet(4, 0, bytes([9])))
    bad[-1] ^= 0xFF
    packets = parser.feed(b"\x00\x13\xff" + good + bytes(bad) + b"\xff" + good[:3])
    packets += parser.feed(good[3:])
    assert packets == [dx.Packet(3, ErrorBit.OVERLOAD, bytes([1, 2]))] * 2
    assert parser.corrupt_packets == 1
    assert parser.rejected_ids == [4]


def test_error_bits_are_named() -> None:
    assert dx.describe_errors(ErrorBit.OVERLOAD | ErrorBit.OVERHEATING) == ["overheating", "overload"]
    assert dx.describe_errors(0) == []
    assert Instruction.SYNC_WRITE == 0x83


def test_position_and_speed_units() -> None:
    assert dx.position_to_radians(512) == 0.0
    assert dx.position_to_radians(0) == pytest.approx(-math.radians(150), abs=0.01)
    assert dx.position_to_radians(1023) == pytest.approx(math.radians(150), abs=0.01)
    assert dx.radians_to_position(math.radians(30)) == pytest.approx(512 + 30 / 300 * 1023, abs=0.6)
    with pytest.raises(ValueError, match="outside the AX-12 range"):
        dx.radians_to_position(2.7)
    assert dx.speed_to_moving_speed(1.0) == round(1.0 / (0.111 * 2 * math.pi / 60))
    assert dx.speed_to_moving_speed(0.0) == 1  # 0 would mean full speed
    assert dx.present_speed_to_rad_s(0x400 | 100) == pytest.approx(-100 * 0.111 * 2 * math.pi / 60)
    assert dx.present_load_to_fraction(0x400 | 1023) == -1.0
    assert dx.present_load_to_fraction(dx.load_fraction_to_raw(0.25)) == pytest.approx(0.25, abs=1e-3)


def test_state_block_decodes_every_field() -> None:
    block = (dx.u16(600) + dx.u16(0x400 | 50) + dx.u16(200) + bytes([121, 45])
             + bytes([0, 0, 1]))  # voltage 12.1 V, 45 degC, registered 0, (44..45), moving 1
    assert len(block) == dx.STATE_BLOCK_LENGTH
    state = dx.decode_state_block(block)
    assert state.position == pytest.approx(dx.position_to_radians(600))
    assert state.velocity < 0
    assert state.load == pytest.approx(200 / 1023)
    assert (state.voltage, state.temperature, state.moving) == (12.1, 45.0, True)
    with pytest.raises(dx.PacketError):
        dx.decode_state_block(block[:-1])
