"""iRobot Create Open Interface codec: commands to bytes, sensor stream bytes to values.

The M3 robots and the scanning robot drive on iRobot Create bases (paper section 3.1). This module
knows the bytes of the Open Interface (OI) and nothing else: no serial port, no ROS. Facts from the
Create OI specification (``HARDWARE.md``):

* commands are an opcode followed by data bytes; two-byte values are signed or unsigned big-endian;
* Drive Direct ``[145, right_hi, right_lo, left_hi, left_lo]`` in mm/s, right wheel first,
  each within +-500 mm/s;
* a stream frame is ``19, n, (packet id, data...)..., checksum`` where ``n`` counts the bytes
  between itself and the checksum, and all bytes of the frame sum to 0 modulo 256.

:class:`StreamParser` turns an arbitrary byte stream (garbage, partial frames, corrupt checksums)
into valid frames, resynchronising on the next header and counting what it discarded.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from enum import IntEnum

STREAM_HEADER = 19
MAX_WHEEL_SPEED_MM_S = 500  # |v| of each wheel in Drive Direct
STRAIGHT_RADIUS = 32767  # Drive: special radius values
SPIN_CLOCKWISE = -1
SPIN_COUNTER_CLOCKWISE = 1


class Opcode(IntEnum):
    RESET = 7
    START = 128
    BAUD = 129
    SAFE = 131
    FULL = 132
    POWER = 133
    DRIVE = 137
    LEDS = 139
    SONG = 140
    PLAY = 141
    SENSORS = 142
    DOCK = 143
    DRIVE_DIRECT = 145
    DRIVE_PWM = 146
    STREAM = 148
    QUERY_LIST = 149
    PAUSE_RESUME_STREAM = 150
    STOP = 173


class OIMode(IntEnum):
    """Value of sensor packet 35 (OI mode)."""

    OFF = 0
    PASSIVE = 1
    SAFE = 2
    FULL = 3


class PacketId(IntEnum):
    BUMPS_WHEEL_DROPS = 7
    DISTANCE = 19
    ANGLE = 20
    CHARGING_STATE = 21
    VOLTAGE = 22
    CURRENT = 23
    TEMPERATURE = 24
    BATTERY_CHARGE = 25
    BATTERY_CAPACITY = 26
    OI_MODE = 35
    LEFT_ENCODER = 43
    RIGHT_ENCODER = 44


@dataclass(frozen=True)
class PacketSpec:
    name: str
    size: int  # data bytes
    signed: bool
    unit: str


SENSOR_PACKETS: dict[int, PacketSpec] = {
    PacketId.BUMPS_WHEEL_DROPS: PacketSpec("bumps_wheel_drops", 1, False, "bits"),
    PacketId.DISTANCE: PacketSpec("distance", 2, True, "mm since last report"),
    PacketId.ANGLE: PacketSpec("angle", 2, True, "degrees since last report, counter-clockwise"),
    PacketId.CHARGING_STATE: PacketSpec("charging_state", 1, False, "code"),
    PacketId.VOLTAGE: PacketSpec("voltage", 2, False, "mV"),
    PacketId.CURRENT: PacketSpec("current", 2, True, "mA"),
    PacketId.TEMPERATURE: PacketSpec("temperature", 1, True, "degC"),
    PacketId.BATTERY_CHARGE: PacketSpec("battery_charge", 2, False, "mAh"),
    PacketId.BATTERY_CAPACITY: PacketSpec("battery_capacity", 2, False, "mAh"),
    PacketId.OI_MODE: PacketSpec("oi_mode", 1, False, "mode"),
    PacketId.LEFT_ENCODER: PacketSpec("left_encoder", 2, False, "counts, wraps at 65535"),
    PacketId.RIGHT_ENCODER: PacketSpec("right_encoder", 2, False, "counts, wraps at 65535"),
}

# What the driver streams: odometry inputs of both Create generations, hazards, battery, mode.
CREATE1_STREAM = (
    PacketId.BUMPS_WHEEL_DROPS, PacketId.DISTANCE, PacketId.ANGLE, PacketId.CHARGING_STATE,
    PacketId.VOLTAGE, PacketId.CURRENT, PacketId.TEMPERATURE, PacketId.BATTERY_CHARGE,
    PacketId.BATTERY_CAPACITY, PacketId.OI_MODE,
)
CREATE2_STREAM = (*CREATE1_STREAM, PacketId.LEFT_ENCODER, PacketId.RIGHT_ENCODER)

CHARGING_STATES = {
    0: "not charging", 1: "reconditioning charging", 2: "full charging", 3: "trickle charging",
    4: "waiting", 5: "charging fault",
}


class FrameError(ValueError):
    """A stream frame that is not valid (checksum, unknown packet id, wrong length)."""


def _int16(value: int) -> bytes:
    if not -32768 <= value <= 32767:
        raise ValueError(f"{value} does not fit a signed 16-bit OI value")
    return (value & 0xFFFF).to_bytes(2, "big")


# ----------------------------------------------------------------------------- commands


def start() -> bytes:
    """Start the OI (the robot enters Passive mode)."""
    return bytes([Opcode.START])


def mode_command(mode: OIMode) -> bytes:
    """Enter Safe or Full mode (the robot must be started)."""
    if mode == OIMode.SAFE:
        return bytes([Opcode.SAFE])
    if mode == OIMode.FULL:
        return bytes([Opcode.FULL])
    raise ValueError(f"only Safe and Full mode can be commanded, not {mode.name}")


def drive_direct(right_mm_s: int, left_mm_s: int) -> bytes:
    """Drive Direct: right then left wheel velocity, mm/s, each within +-500."""
    for name, value in (("right", right_mm_s), ("left", left_mm_s)):
        if abs(value) > MAX_WHEEL_SPEED_MM_S:
            raise ValueError(f"{name} wheel speed {value} mm/s exceeds +-{MAX_WHEEL_SPEED_MM_S}")
    return bytes([Opcode.DRIVE_DIRECT]) + _int16(right_mm_s) + _int16(left_mm_s)


def drive(velocity_mm_s: int, radius_mm: int) -> bytes:
    """Drive: velocity (mm/s) along an arc of `radius_mm` (32767 straight, +-1 spin in place)."""
    if abs(velocity_mm_s) > MAX_WHEEL_SPEED_MM_S:
        raise ValueError(f"velocity {velocity_mm_s} mm/s exceeds +-{MAX_WHEEL_SPEED_MM_S}")
    return bytes([Opcode.DRIVE]) + _int16(velocity_mm_s) + _int16(radius_mm)


def stream(packet_ids: Iterable[int]) -> bytes:
    """Ask for a sensor stream of `packet_ids` (one frame every 15 ms)."""
    ids = [int(p) for p in packet_ids]
    unknown = [p for p in ids if p not in SENSOR_PACKETS]
    if unknown:
        raise ValueError(f"unsupported sensor packet ids {unknown}")
    return bytes([Opcode.STREAM, len(ids), *ids])


def pause_resume_stream(resume: bool) -> bytes:
    return bytes([Opcode.PAUSE_RESUME_STREAM, 1 if resume else 0])


def stop_oi() -> bytes:
    """Stop the OI (Create 2): the robot stops listening until the next Start."""
    return bytes([Opcode.STOP])


# Data bytes following each opcode the emulator understands; None: variable (see command_length).
COMMAND_DATA_BYTES: dict[int, int | None] = {
    Opcode.RESET: 0, Opcode.START: 0, Opcode.BAUD: 1, Opcode.SAFE: 0, Opcode.FULL: 0,
    Opcode.POWER: 0, Opcode.DRIVE: 4, Opcode.LEDS: 3, Opcode.SONG: None, Opcode.PLAY: 1,
    Opcode.SENSORS: 1, Opcode.DOCK: 0, Opcode.DRIVE_DIRECT: 4, Opcode.DRIVE_PWM: 4,
    Opcode.STREAM: None, Opcode.QUERY_LIST: None, Opcode.PAUSE_RESUME_STREAM: 1, Opcode.STOP: 0,
}


def command_length(data: bytes) -> int | None:
    """Total length of the command at the start of `data`; None if more bytes are needed.

    Raises ValueError for a byte that is not a known opcode.
    """
    opcode = data[0]
    if opcode not in COMMAND_DATA_BYTES:
        raise ValueError(f"unknown opcode {opcode}")
    fixed = COMMAND_DATA_BYTES[opcode]
    if fixed is not None:
        return 1 + fixed
    if len(data) < 2:
        return None
    if opcode == Opcode.SONG:  # song number, length n, then n (note, duration) pairs
        if len(data) < 3:
            return None
        return 3 + 2 * data[2]
    return 2 + data[1]  # Stream / Query List: n, then n packet ids


# ----------------------------------------------------------------------------- sensor stream


def encode_sensor_values(values: Mapping[int, int]) -> bytes:
    """(id, data...) pairs of a stream frame or Query List reply, in the mapping's order."""
    out = bytearray()
    for packet_id, value in values.items():
        spec = SENSOR_PACKETS[packet_id]
        if spec.size == 1:
            out += bytes([packet_id, value & 0xFF])
        else:
            out += bytes([packet_id]) + (value & 0xFFFF).to_bytes(2, "big")
    return bytes(out)


def stream_frame(values: Mapping[int, int]) -> bytes:
    """A complete stream frame with its header, length and checksum."""
    payload = encode_sensor_values(values)
    body = bytes([STREAM_HEADER, len(payload)]) + payload
    return body + bytes([(-sum(body)) & 0xFF])


def decode_sensor_values(payload: bytes) -> dict[int, int]:
    """The (id -> value) pairs of a stream frame's payload; FrameError when it does not parse."""
    values: dict[int, int] = {}
    i = 0
    while i < len(payload):
        packet_id = payload[i]
        spec = SENSOR_PACKETS.get(packet_id)
        if spec is None:
            raise FrameError(f"unknown sensor packet id {packet_id}")
        data = payload[i + 1 : i + 1 + spec.size]
        if len(data) != spec.size:
            raise FrameError(f"packet {packet_id} truncated")
        values[packet_id] = int.from_bytes(data, "big", signed=spec.signed)
        i += 1 + spec.size
    return values


def payload_length(packet_ids: Iterable[int]) -> int:
    """The `n` byte of frames that stream exactly `packet_ids`."""
    return sum(1 + SENSOR_PACKETS[p].size for p in packet_ids)


class StreamParser:
    """Splits the Create's byte stream into valid frames.

    Garbage between frames, partial frames and frames with a bad checksum are skipped: the parser
    then looks for the next header byte after the start of the rejected frame. ``corrupt_frames``
    counts frames whose header and length looked right but whose checksum or content did not;
    ``discarded_bytes`` counts every byte that was not part of a valid frame.
    """

    def __init__(self, packet_ids: Iterable[int]) -> None:
        self.packet_ids = tuple(int(p) for p in packet_ids)
        self.expected_length = payload_length(self.packet_ids)
        self.buffer = bytearray()
        self.frames = 0
        self.corrupt_frames = 0
        self.discarded_bytes = 0

    def reset(self) -> None:
        self.buffer.clear()

    def feed(self, data: bytes) -> list[dict[int, int]]:
        self.buffer += data
        frames: list[dict[int, int]] = []
        n = self.expected_length
        while True:
            start = self.buffer.find(STREAM_HEADER)
            if start < 0:
                self.discarded_bytes += len(self.buffer)
                self.buffer.clear()
                return frames
            if start:
                self.discarded_bytes += start
                del self.buffer[:start]
            if len(self.buffer) < 2:
                return frames
            if self.buffer[1] != n:  # a 19 inside garbage or data: not a frame start
                self.discarded_bytes += 1
                del self.buffer[:1]
                continue
            if len(self.buffer) < n + 3:
                return frames
            frame = bytes(self.buffer[: n + 3])
            try:
                if sum(frame) & 0xFF:
                    raise FrameError("checksum")
                values = decode_sensor_values(frame[2:-1])
                if tuple(values) != self.packet_ids:
                    raise FrameError("unexpected packet ids")
            except FrameError:
                self.corrupt_frames += 1
                self.discarded_bytes += 1
                del self.buffer[:1]
                continue
            del self.buffer[: n + 3]
            self.frames += 1
            frames.append(values)


@dataclass(frozen=True)
class Hazards:
    """Sensor packet 7: bumpers and wheel drops."""

    bump_right: bool
    bump_left: bool
    drop_right: bool
    drop_left: bool

    @classmethod
    def from_byte(cls, bits: int) -> Hazards:
        return cls(bool(bits & 1), bool(bits & 2), bool(bits & 4), bool(bits & 8))

    def to_byte(self) -> int:
        return (
            int(self.bump_right) | int(self.bump_left) << 1 | int(self.drop_right) << 2
            | int(self.drop_left) << 3
        )

    @property
    def bumped(self) -> bool:
        return self.bump_left or self.bump_right

    @property
    def wheel_dropped(self) -> bool:
        return self.drop_left or self.drop_right

    def describe(self) -> str:
        parts = [
            name for name, on in (
                ("left bumper", self.bump_left), ("right bumper", self.bump_right),
                ("left wheel dropped", self.drop_left), ("right wheel dropped", self.drop_right),
            ) if on
        ]
        return ", ".join(parts) if parts else "none"
