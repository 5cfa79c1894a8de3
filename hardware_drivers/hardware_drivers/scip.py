"""Hokuyo SCIP 2.0 codec: commands, replies, line checksums, character encodings, scan geometry.

The M3 robots find the tiles to pick with a Hokuyo URG laser range finder (paper section 3.1).
This module knows SCIP text and nothing about serial ports or ROS. Facts from the SCIP 2.0
specification (``HARDWARE.md``):

* a command is text ending in LF; the reply echoes it, then a status line ``SS`` + sum, then data
  lines each followed by their own sum character, and an empty line ends the reply;
* the sum of a line is ``(sum(bytes) & 0x3F) + 0x30`` over the line without its sum character
  (parameter lines ``KEY:VALUE;S``: over ``KEY:VALUE``);
* values are encoded 6 bits per character (character - 0x30), most significant first: 2 characters
  (MS/GS), 3 (MD/GD ranges), 4 (time stamps);
* MD data come in blocks of 64 characters, each line followed by its sum;
* the angle of step s is (s - AFRT) * 2 pi / ARES, counter-clockwise seen from above.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

LF = b"\n"
DATA_LINE_LENGTH = 64
MAX_REPLY_BYTES = 65536


class ScipError(ValueError):
    """A reply that is not valid SCIP: bad checksum, wrong echo, unexpected format."""


def checksum(data: bytes) -> int:
    return (sum(data) & 0x3F) + 0x30


def encode(value: int, chars: int) -> bytes:
    if not 0 <= value < 1 << (6 * chars):
        raise ValueError(f"{value} does not fit {chars} SCIP characters")
    return bytes(((value >> (6 * (chars - 1 - i))) & 0x3F) + 0x30 for i in range(chars))


def decode(data: bytes) -> int:
    value = 0
    for c in data:
        if not 0x30 <= c < 0x70:
            raise ScipError(f"byte {c:#x} is not a SCIP encoded character")
        value = (value << 6) | (c - 0x30)
    return value


def decode_array(data: bytes, chars: int) -> list[int]:
    if len(data) % chars:
        raise ScipError(f"{len(data)} data characters are not a multiple of {chars}")
    return [decode(data[i : i + chars]) for i in range(0, len(data), chars)]


def with_sum(line: bytes) -> bytes:
    """A data or status line followed by its sum character."""
    return line + bytes([checksum(line)])


def split_data_lines(encoded: bytes) -> list[bytes]:
    """Encoded data cut into lines of 64 characters, each followed by its sum."""
    return [
        with_sum(encoded[i : i + DATA_LINE_LENGTH])
        for i in range(0, len(encoded), DATA_LINE_LENGTH)
    ]


# ----------------------------------------------------------------------------- commands


def command(text: str) -> bytes:
    return text.encode("ascii") + LF


def md_command(start: int, end: int, cluster: int = 1, interval: int = 0, scans: int = 0) -> bytes:
    """Continuous 3-character scans of steps start..end (scans=0: until QT)."""
    return command(f"MD{start:04d}{end:04d}{cluster:02d}{interval:01d}{scans:02d}")


def gd_command(start: int, end: int, cluster: int = 1) -> bytes:
    return command(f"GD{start:04d}{end:04d}{cluster:02d}")


# ----------------------------------------------------------------------------- replies


@dataclass(frozen=True)
class Reply:
    echo: bytes
    status: bytes  # "00", "99", "0E"... (SCIP 1.1: a single character such as "0" or "E")
    lines: tuple[bytes, ...]  # the lines after the status line, still with their sum character
    status_sum_ok: bool


class ReplySplitter:
    """Cuts the sensor's byte stream into replies (blocks ending with an empty line).

    A block that does not start with an expected echo is garbage (or a reply damaged by garbage);
    the splitter hands every block over and the caller decides, but it bounds memory: a stream
    without a blank line for MAX_REPLY_BYTES is dropped and counted.
    """

    def __init__(self) -> None:
        self.buffer = bytearray()
        self.dropped_bytes = 0

    def reset(self) -> None:
        self.buffer.clear()

    def feed(self, data: bytes) -> list[bytes]:
        self.buffer += data
        blocks: list[bytes] = []
        while True:
            end = self.buffer.find(b"\n\n")
            if end < 0:
                if len(self.buffer) > MAX_REPLY_BYTES:
                    self.dropped_bytes += len(self.buffer)
                    self.buffer.clear()
                return blocks
            block = bytes(self.buffer[:end])
            del self.buffer[: end + 2]
            # empty lines before a reply (a lone LF after garbage) carry nothing
            blocks.append(block.lstrip(b"\n"))


def parse_reply(block: bytes) -> Reply:
    """Echo, status and remaining lines of one reply block (without its terminating blank line)."""
    lines = block.split(LF)
    if len(lines) < 2:
        raise ScipError("reply without a status line")
    echo, status_line, rest = lines[0], lines[1], tuple(lines[2:])
    if len(status_line) == 3:  # SCIP 2.0: two status characters and their sum
        status = status_line[:2]
        ok = checksum(status) == status_line[2]
    else:
        status, ok = status_line, True  # SCIP 1.1 statuses carry no sum
    return Reply(echo, status, rest, ok)


def verified(line: bytes) -> bytes:
    """A data line without its sum character; ScipError if the sum does not match."""
    if len(line) < 2:
        raise ScipError("data line too short")
    if checksum(line[:-1]) != line[-1]:
        raise ScipError(f"checksum mismatch in line {line[:16]!r}...")
    return line[:-1]


def parse_parameters(reply: Reply) -> dict[str, str]:
    """KEY:VALUE;S lines of VV, PP and II replies, every sum verified."""
    values: dict[str, str] = {}
    for line in reply.lines:
        if not line:
            continue
        text, sep, sum_char = line.rpartition(b";")
        if not sep or len(sum_char) != 1 or checksum(text) != sum_char[0]:
            raise ScipError(f"bad parameter line {line!r}")
        key, colon, value = text.partition(b":")
        if not colon:
            raise ScipError(f"bad parameter line {line!r}")
        values[key.decode("ascii", "replace")] = value.decode("ascii", "replace")
    return values


def parameter_lines(values: dict[str, str]) -> list[bytes]:
    """Encode KEY:VALUE;S lines (used by the emulator)."""
    out = []
    for key, value in values.items():
        text = f"{key}:{value}".encode("ascii")
        out.append(text + b";" + bytes([checksum(text)]))
    return out


@dataclass(frozen=True)
class ScanData:
    timestamp: int  # ms, the sensor's clock (wraps at 2^24)
    ranges: list[int]  # mm, raw (values below DMIN are error codes)


def parse_scan(reply: Reply, chars: int = 3) -> ScanData:
    """Time stamp and ranges of an MD/GD scan reply; every line's sum is verified."""
    if not reply.lines:
        raise ScipError("scan reply without a time stamp")
    stamp_line = verified(reply.lines[0])
    if len(stamp_line) != 4:
        raise ScipError("time stamp line is not 4 characters")
    data = b"".join(verified(line) for line in reply.lines[1:])
    return ScanData(decode(stamp_line), decode_array(data, chars))


def scan_reply(echo: bytes, status: bytes, timestamp: int, ranges: Sequence[int], chars: int = 3) -> bytes:
    """A complete scan reply (used by the emulator)."""
    encoded = b"".join(encode(r, chars) for r in ranges)
    lines = [echo, with_sum(status), with_sum(encode(timestamp, 4)), *split_data_lines(encoded)]
    return LF.join(lines) + LF + LF


def status_reply(echo: bytes, status: bytes, lines: Sequence[bytes] = ()) -> bytes:
    return LF.join([echo, with_sum(status), *lines]) + LF + LF


# ----------------------------------------------------------------------------- sensor geometry


@dataclass(frozen=True)
class SensorParameters:
    """The PP reply: the sensor's model and measuring geometry."""

    model: str
    dmin: int  # mm
    dmax: int  # mm
    ares: int  # steps per full turn
    amin: int  # first measurable step
    amax: int  # last measurable step
    afrt: int  # step on the sensor's front axis
    scan_rpm: int

    @classmethod
    def from_pp(cls, values: dict[str, str]) -> SensorParameters:
        try:
            return cls(
                model=values.get("MODL", "unknown"),
                dmin=int(values["DMIN"]), dmax=int(values["DMAX"]), ares=int(values["ARES"]),
                amin=int(values["AMIN"]), amax=int(values["AMAX"]), afrt=int(values["AFRT"]),
                scan_rpm=int(values["SCAN"]),
            )
        except (KeyError, ValueError) as error:
            raise ScipError(f"PP reply lacks a valid parameter: {error}") from None

    def to_pp(self) -> dict[str, str]:
        return {
            "MODL": self.model, "DMIN": str(self.dmin), "DMAX": str(self.dmax),
            "ARES": str(self.ares), "AMIN": str(self.amin), "AMAX": str(self.amax),
            "AFRT": str(self.afrt), "SCAN": str(self.scan_rpm),
        }

    def step_angle(self, step: float) -> float:
        """Angle (rad) of a step, 0 on the front axis, counter-clockwise positive."""
        return (step - self.afrt) * 2.0 * math.pi / self.ares

    @property
    def angle_increment(self) -> float:
        return 2.0 * math.pi / self.ares

    @property
    def scan_time(self) -> float:
        """Seconds per revolution."""
        return 60.0 / self.scan_rpm


URG_04LX = SensorParameters(
    model="URG-04LX(Hokuyo Automatic Co.,Ltd.)", dmin=20, dmax=5600, ares=1024, amin=44, amax=725,
    afrt=384, scan_rpm=600,
)
