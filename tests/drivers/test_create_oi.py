"""The Create Open Interface codec: command bytes as the OI specification gives them, stream
frames, and a stream parser that survives garbage, partial frames and bad checksums."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hardware_drivers import create_oi
from hardware_drivers.create_oi import CREATE1_STREAM, CREATE2_STREAM, Hazards, OIMode, PacketId, StreamParser


def test_commands_match_the_specification_examples() -> None:
    # OI spec: "drive backward at 200 mm/s turning at a radius of 500 mm: [137] [255] [56] [1] [244]"
    assert create_oi.drive(-200, 500) == bytes([137, 255, 56, 1, 244])
    assert create_oi.drive_direct(-200, 500) == bytes([145, 255, 56, 1, 244])  # right wheel first
    assert create_oi.stream([7, 19]) == bytes([148, 2, 7, 19])
    assert create_oi.start() == bytes([128])
    assert create_oi.mode_command(OIMode.SAFE) == bytes([131])
    assert create_oi.mode_command(OIMode.FULL) == bytes([132])
    assert create_oi.pause_resume_stream(False) == bytes([150, 0])


def test_commands_refuse_values_outside_the_specification() -> None:
    with pytest.raises(ValueError, match="500"):
        create_oi.drive_direct(501, 0)
    with pytest.raises(ValueError, match="Safe and Full"):
        create_oi.mode_command(OIMode.PASSIVE)
    with pytest.raises(ValueError, match="unsupported"):
        create_oi.stream([99])


def test_command_lengths_for_the_emulator() -> None:
    assert create_oi.command_length(create_oi.drive_direct(10, 10)) == 5
    assert create_oi.command_length(bytes([148])) is None  # needs the count first
    assert create_oi.command_length(create_oi.stream(CREATE1_STREAM)) == 2 + len(CREATE1_STREAM)
    with pytest.raises(ValueError, match="unknown opcode"):
        create_oi.command_length(bytes([3]))


def _values(distance: int = 12, angle: int = -3, bumps: int = 0) -> dict[int, int]:
    values = {p: 0 for p in CREATE1_STREAM}
    values.update({PacketId.DISTANCE: distance, PacketId.ANGLE: angle, PacketId.BUMPS_WHEEL_DROPS: bumps,
                   PacketId.VOLTAGE: 15800, PacketId.CURRENT: -500, PacketId.TEMPERATURE: -2,
                   PacketId.OI_MODE: 2})
    return values


def test_a_frame_sums_to_zero_and_decodes_to_its_values() -> None:
    frame = create_oi.stream_frame(_values())
    assert frame[0] == 19 and frame[1] == create_oi.payload_length(CREATE1_STREAM)
    assert sum(frame) % 256 == 0
    assert create_oi.decode_sensor_values(frame[2:-1]) == _values()


def test_parser_reassembles_frames_fed_byte_by_byte() -> None:
    parser = StreamParser(CREATE1_STREAM)
    frames = []
    for byte in create_oi.stream_frame(_values()) * 3:
        frames += parser.feed(bytes([byte]))
    assert frames == [_values()] * 3
    assert parser.corrupt_frames == 0 and parser.discarded_bytes == 0


def test_parser_resynchronises_after_garbage_partial_and_corrupt_frames() -> None:
    parser = StreamParser(CREATE1_STREAM)
    good = create_oi.stream_frame(_values(distance=19))  # a data byte equal to the header
    corrupt = bytearray(create_oi.stream_frame(_values(distance=5)))
    corrupt[-1] ^= 0x01
    partial = create_oi.stream_frame(_values(distance=7))[:9]
    garbage = bytes([0, 255, 19, 3, 19, 99, 42])
    frames = parser.feed(garbage + good + bytes(corrupt) + good + partial + good)
    assert frames == [_values(distance=19)] * 3
    assert parser.corrupt_frames >= 2  # the bad checksum and the frame cut short
    assert parser.discarded_bytes >= len(garbage)


def test_create2_frames_carry_wrapping_encoder_counts() -> None:
    values = {p: 0 for p in CREATE2_STREAM}
    values[PacketId.LEFT_ENCODER] = 65535
    values[PacketId.RIGHT_ENCODER] = 3
    parser = StreamParser(CREATE2_STREAM)
    assert parser.feed(create_oi.stream_frame(values)) == [values]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.integers(-500, 500), st.integers(-90, 90), st.integers(0, 15)),
             min_size=1, max_size=8),
    st.lists(st.binary(max_size=12), min_size=9, max_size=9),
)
def test_every_valid_frame_survives_random_garbage_between_frames(
        frames_values: list[tuple[int, int, int]], garbage: list[bytes]) -> None:
    expected = [_values(d, a, b) for d, a, b in frames_values]
    data = b"".join(g + create_oi.stream_frame(v) for g, v in zip(garbage, expected, strict=False))
    parser = StreamParser(CREATE1_STREAM)
    received = []
    for start in range(0, len(data), 7):
        received += parser.feed(data[start : start + 7])
    assert received[-len(expected):] == expected


def test_hazard_bits() -> None:
    hazards = Hazards.from_byte(0b1010)
    assert hazards == Hazards(bump_right=False, bump_left=True, drop_right=False, drop_left=True)
    assert hazards.to_byte() == 0b1010
    assert hazards.bumped and hazards.wheel_dropped
    assert hazards.describe() == "left bumper, left wheel dropped"
    assert Hazards.from_byte(0).describe() == "none"
