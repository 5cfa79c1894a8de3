"""Robotis Dynamixel Protocol 1.0 codec and the AX-12 control table.

The CrustCrawler arm of the M3 robots (paper section 3.1) is a chain of AX-12 servos on one
half-duplex bus. This module knows packets and units, nothing about serial ports or ROS. Facts from
the Protocol 1.0 and AX-12 specifications (``HARDWARE.md``):

* instruction ``FF FF ID LEN INST params... CHK`` and status ``FF FF ID LEN ERR params... CHK``,
  LEN = len(params) + 2, CHK = ~(ID + LEN + INST/ERR + sum(params)) & 0xFF;
* error bits: input voltage 1, angle limit 2, overheating 4, range 8, checksum 16, overload 32,
  instruction 64; multi-byte values little-endian;
* position 0..1023 over 300 degrees (512 is the middle), speed unit about 0.111 rpm.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum, IntFlag

HEADER = b"\xff\xff"
BROADCAST_ID = 0xFE
MAX_ID = 0xFD


class Instruction(IntEnum):
    PING = 1
    READ = 2
    WRITE = 3
    REG_WRITE = 4
    ACTION = 5
    RESET = 6
    SYNC_WRITE = 0x83


class ErrorBit(IntFlag):
    INPUT_VOLTAGE = 1
    ANGLE_LIMIT = 2
    OVERHEATING = 4
    RANGE = 8
    CHECKSUM = 16
    OVERLOAD = 32
    INSTRUCTION = 64


ERROR_NAMES = {
    ErrorBit.INPUT_VOLTAGE: "input voltage",
    ErrorBit.ANGLE_LIMIT: "angle limit",
    ErrorBit.OVERHEATING: "overheating",
    ErrorBit.RANGE: "range",
    ErrorBit.CHECKSUM: "checksum",
    ErrorBit.OVERLOAD: "overload",
    ErrorBit.INSTRUCTION: "instruction",
}


def describe_errors(error: int) -> list[str]:
    """Names of the error bits set in a status packet's error byte."""
    return [name for bit, name in ERROR_NAMES.items() if error & bit]


class AX12(IntEnum):
    """AX-12 control table addresses."""

    MODEL_NUMBER = 0
    FIRMWARE_VERSION = 2
    ID = 3
    BAUD_RATE = 4
    RETURN_DELAY_TIME = 5
    CW_ANGLE_LIMIT = 6
    CCW_ANGLE_LIMIT = 8
    TEMPERATURE_LIMIT = 11
    MIN_VOLTAGE_LIMIT = 12
    MAX_VOLTAGE_LIMIT = 13
    MAX_TORQUE = 14
    STATUS_RETURN_LEVEL = 16
    ALARM_LED = 17
    ALARM_SHUTDOWN = 18
    TORQUE_ENABLE = 24
    LED = 25
    CW_COMPLIANCE_MARGIN = 26
    CCW_COMPLIANCE_MARGIN = 27
    CW_COMPLIANCE_SLOPE = 28
    CCW_COMPLIANCE_SLOPE = 29
    GOAL_POSITION = 30
    MOVING_SPEED = 32
    TORQUE_LIMIT = 34
    PRESENT_POSITION = 36
    PRESENT_SPEED = 38
    PRESENT_LOAD = 40
    PRESENT_VOLTAGE = 42
    PRESENT_TEMPERATURE = 43
    REGISTERED = 44
    MOVING = 46
    LOCK = 47
    PUNCH = 48


@dataclass(frozen=True)
class Field:
    address: int
    size: int
    default: int
    writable: bool


AX12_MODEL = 12
# The control table with the AX-12's factory defaults (EEPROM 0-23, RAM 24-49).
AX12_FIELDS: tuple[Field, ...] = (
    Field(AX12.MODEL_NUMBER, 2, AX12_MODEL, False),
    Field(AX12.FIRMWARE_VERSION, 1, 24, False),
    Field(AX12.ID, 1, 1, True),
    Field(AX12.BAUD_RATE, 1, 1, True),
    Field(AX12.RETURN_DELAY_TIME, 1, 250, True),
    Field(AX12.CW_ANGLE_LIMIT, 2, 0, True),
    Field(AX12.CCW_ANGLE_LIMIT, 2, 1023, True),
    Field(AX12.TEMPERATURE_LIMIT, 1, 70, True),
    Field(AX12.MIN_VOLTAGE_LIMIT, 1, 60, True),
    Field(AX12.MAX_VOLTAGE_LIMIT, 1, 140, True),
    Field(AX12.MAX_TORQUE, 2, 1023, True),
    Field(AX12.STATUS_RETURN_LEVEL, 1, 2, True),
    Field(AX12.ALARM_LED, 1, 36, True),
    Field(AX12.ALARM_SHUTDOWN, 1, 36, True),
    Field(AX12.TORQUE_ENABLE, 1, 0, True),
    Field(AX12.LED, 1, 0, True),
    Field(AX12.CW_COMPLIANCE_MARGIN, 1, 1, True),
    Field(AX12.CCW_COMPLIANCE_MARGIN, 1, 1, True),
    Field(AX12.CW_COMPLIANCE_SLOPE, 1, 32, True),
    Field(AX12.CCW_COMPLIANCE_SLOPE, 1, 32, True),
    Field(AX12.GOAL_POSITION, 2, 512, True),
    Field(AX12.MOVING_SPEED, 2, 0, True),
    Field(AX12.TORQUE_LIMIT, 2, 1023, True),
    Field(AX12.PRESENT_POSITION, 2, 512, False),
    Field(AX12.PRESENT_SPEED, 2, 0, False),
    Field(AX12.PRESENT_LOAD, 2, 0, False),
    Field(AX12.PRESENT_VOLTAGE, 1, 120, False),
    Field(AX12.PRESENT_TEMPERATURE, 1, 35, False),
    Field(AX12.REGISTERED, 1, 0, False),
    Field(AX12.MOVING, 1, 0, False),
    Field(AX12.LOCK, 1, 0, True),
    Field(AX12.PUNCH, 2, 32, True),
)
CONTROL_TABLE_SIZE = 50

# One READ covers everything the driver reports per joint: present position .. moving.
STATE_BLOCK_START = AX12.PRESENT_POSITION
STATE_BLOCK_LENGTH = AX12.MOVING - AX12.PRESENT_POSITION + 1
# The driver's READ per joint and cycle: the goal registers the servo holds (goal position, moving
# speed), the torque limit and the state block; a goal write the servo missed shows up at once.
JOINT_BLOCK_START = AX12.GOAL_POSITION
JOINT_BLOCK_LENGTH = AX12.MOVING - AX12.GOAL_POSITION + 1

POSITION_RANGE_RAD = math.radians(300.0)  # 0..1023 spans 300 degrees
POSITION_CENTER = 512
RAD_PER_POSITION = POSITION_RANGE_RAD / 1023.0
RAD_S_PER_SPEED_UNIT = 0.111 * 2.0 * math.pi / 60.0  # 0.111 rpm


class PacketError(ValueError):
    """A packet that is not valid."""


def checksum(body: bytes) -> int:
    """~(ID + LEN + INST/ERR + params) & 0xFF over `body` = ID, LEN, INST/ERR, params."""
    return (~sum(body)) & 0xFF


def _packet(servo_id: int, code: int, params: bytes) -> bytes:
    if not 0 <= servo_id <= BROADCAST_ID:
        raise ValueError(f"servo id {servo_id} outside 0..{BROADCAST_ID}")
    body = bytes([servo_id, len(params) + 2, code]) + bytes(params)
    return HEADER + body + bytes([checksum(body)])


def instruction_packet(servo_id: int, instruction: int, params: bytes = b"") -> bytes:
    return _packet(servo_id, instruction, params)


def status_packet(servo_id: int, error: int, params: bytes = b"") -> bytes:
    return _packet(servo_id, error, params)


def ping(servo_id: int) -> bytes:
    return instruction_packet(servo_id, Instruction.PING)


def read(servo_id: int, address: int, length: int) -> bytes:
    return instruction_packet(servo_id, Instruction.READ, bytes([address, length]))


def write(servo_id: int, address: int, data: bytes) -> bytes:
    return instruction_packet(servo_id, Instruction.WRITE, bytes([address]) + bytes(data))


def sync_write(address: int, data_by_id: Mapping[int, bytes]) -> bytes:
    """One SYNC_WRITE of equally long data blocks to several servos (no status replies)."""
    sizes = {len(d) for d in data_by_id.values()}
    if len(sizes) != 1:
        raise ValueError("SYNC_WRITE needs data blocks of one length")
    size = sizes.pop()
    params = bytearray([address, size])
    for servo_id, data in data_by_id.items():
        params += bytes([servo_id]) + bytes(data)
    return instruction_packet(BROADCAST_ID, Instruction.SYNC_WRITE, bytes(params))


def u16(value: int) -> bytes:
    return int(value).to_bytes(2, "little")


@dataclass(frozen=True)
class Packet:
    """A parsed packet: `code` is the instruction (to a servo) or the error byte (from one)."""

    servo_id: int
    code: int
    params: bytes


class PacketParser:
    """Splits a byte stream into valid packets, resynchronising on the next ``FF FF``.

    ``corrupt_packets`` counts packets rejected for their checksum or an impossible length,
    ``discarded_bytes`` every byte that was not part of a valid packet.
    """

    def __init__(self) -> None:
        self.buffer = bytearray()
        self.packets = 0
        self.corrupt_packets = 0
        self.discarded_bytes = 0
        self.rejected_ids: list[int] = []  # ids of packets rejected for their checksum

    def reset(self) -> None:
        self.buffer.clear()

    def feed(self, data: bytes) -> list[Packet]:
        self.buffer += data
        out: list[Packet] = []
        while True:
            start = self.buffer.find(HEADER)
            if start < 0:
                keep = 1 if self.buffer.endswith(b"\xff") else 0
                self.discarded_bytes += len(self.buffer) - keep
                del self.buffer[: len(self.buffer) - keep]
                return out
            if start:
                self.discarded_bytes += start
                del self.buffer[:start]
            if len(self.buffer) < 4:
                return out
            servo_id, length = self.buffer[2], self.buffer[3]
            if servo_id == 0xFF or length < 2:  # FF FF FF ...: the header starts one byte later
                self.discarded_bytes += 1
                del self.buffer[:1]
                if length < 2 and servo_id != 0xFF:
                    self.corrupt_packets += 1
                continue
            total = 4 + length
            if len(self.buffer) < total:
                return out
            body = bytes(self.buffer[2 : total - 1])
            if checksum(body) != self.buffer[total - 1]:
                self.corrupt_packets += 1
                self.rejected_ids.append(servo_id)
                self.discarded_bytes += 1
                del self.buffer[:1]
                continue
            del self.buffer[:total]
            self.packets += 1
            out.append(Packet(body[0], body[2], body[3:]))


# ----------------------------------------------------------------------------- units


def position_to_radians(position: int) -> float:
    """Servo angle (rad, 0 at position 512, counter-clockwise positive) of a raw position."""
    return (position - POSITION_CENTER) * RAD_PER_POSITION


def radians_to_position(angle: float) -> int:
    """Raw position of a servo angle; ValueError outside the servo's 300 degree range."""
    position = round(angle / RAD_PER_POSITION) + POSITION_CENTER
    if not 0 <= position <= 1023:
        raise ValueError(
            f"servo angle {angle:.3f} rad is outside the AX-12 range "
            f"[{position_to_radians(0):.3f}, {position_to_radians(1023):.3f}] rad"
        )
    return position


def speed_to_moving_speed(rad_s: float) -> int:
    """Moving Speed register for |rad_s|; at least 1, because 0 means 'as fast as possible'."""
    return max(1, min(1023, round(abs(rad_s) / RAD_S_PER_SPEED_UNIT)))


def moving_speed_to_rad_s(raw: int) -> float:
    return (raw & 0x3FF) * RAD_S_PER_SPEED_UNIT


def present_speed_to_rad_s(raw: int) -> float:
    """Present Speed: bits 0-9 magnitude, bit 10 set for clockwise (negative)."""
    magnitude = (raw & 0x3FF) * RAD_S_PER_SPEED_UNIT
    return -magnitude if raw & 0x400 else magnitude


def signed_speed_to_raw(rad_s: float) -> int:
    magnitude = min(1023, round(abs(rad_s) / RAD_S_PER_SPEED_UNIT))
    return magnitude | (0x400 if rad_s < 0 else 0)


def present_load_to_fraction(raw: int) -> float:
    """Present Load as a signed fraction of the maximum torque (bit 10: clockwise)."""
    magnitude = (raw & 0x3FF) / 1023.0
    return -magnitude if raw & 0x400 else magnitude


def load_fraction_to_raw(fraction: float) -> int:
    magnitude = min(1023, round(abs(fraction) * 1023))
    return magnitude | (0x400 if fraction < 0 else 0)


@dataclass(frozen=True)
class ServoState:
    """The state block of one servo (addresses 36..46), in SI units."""

    position: float  # rad, servo frame
    velocity: float  # rad/s
    load: float  # fraction of max torque, signed
    voltage: float  # V
    temperature: float  # degC
    moving: bool


@dataclass(frozen=True)
class HeldGoal:
    """The goal registers of one servo, raw: what it is heading for and how fast."""

    position: int
    moving_speed: int


def decode_joint_block(params: bytes) -> tuple[HeldGoal, ServoState]:
    """Decode a READ of JOINT_BLOCK_LENGTH bytes from JOINT_BLOCK_START."""
    if len(params) != JOINT_BLOCK_LENGTH:
        raise PacketError(f"joint block of {len(params)} bytes, expected {JOINT_BLOCK_LENGTH}")

    def word(address: int) -> int:
        i = address - JOINT_BLOCK_START
        return params[i] | params[i + 1] << 8

    goal = HeldGoal(word(AX12.GOAL_POSITION), word(AX12.MOVING_SPEED))
    return goal, decode_state_block(params[STATE_BLOCK_START - JOINT_BLOCK_START :])


def decode_state_block(params: bytes) -> ServoState:
    """Decode a READ of STATE_BLOCK_LENGTH bytes from STATE_BLOCK_START."""
    if len(params) != STATE_BLOCK_LENGTH:
        raise PacketError(f"state block of {len(params)} bytes, expected {STATE_BLOCK_LENGTH}")

    def word(address: int) -> int:
        i = address - STATE_BLOCK_START
        return params[i] | params[i + 1] << 8

    def byte(address: int) -> int:
        return params[address - STATE_BLOCK_START]

    return ServoState(
        position=position_to_radians(word(AX12.PRESENT_POSITION)),
        velocity=present_speed_to_rad_s(word(AX12.PRESENT_SPEED)),
        load=present_load_to_fraction(word(AX12.PRESENT_LOAD)),
        voltage=byte(AX12.PRESENT_VOLTAGE) / 10.0,
        temperature=float(byte(AX12.PRESENT_TEMPERATURE)),
        moving=bool(byte(AX12.MOVING)),
    )
