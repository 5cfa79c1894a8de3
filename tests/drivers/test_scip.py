"""The SCIP 2.0 codec against the specification's examples: encodings, line sums, replies."""

from __future__ import annotations

import math

import pytest

from hardware_drivers import scip
from hardware_drivers.scip import URG_04LX, ScipError


def test_encodings_match_the_specification_examples() -> None:
    assert scip.encode(1234, 2) == b"CB" and scip.decode(b"CB") == 1234
    assert scip.encode(5432, 3) == b"1Dh" and scip.decode(b"1Dh") == 5432
    assert scip.encode(16_000_000, 4) == b"m2@0" and scip.decode(b"m2@0") == 16_000_000
    assert scip.decode_array(b"1Dh1Dh", 3) == [5432, 5432]
    with pytest.raises(ScipError):
        scip.decode(b"\x10")


def test_line_sums_match_the_specification_examples() -> None:
    assert scip.with_sum(b"00") == b"00P"
    assert scip.with_sum(b"99") == b"99b"
    pp = scip.Reply(b"PP", b"00", (b"DMIN:20;4", b"DMAX:5600;_", b"AMIN:44;7", b"AMAX:725;o", b"AFRT:384;6",
                                   b"SCAN:600;e"), True)
    assert scip.parse_parameters(pp)["AFRT"] == "384"
    with pytest.raises(ScipError, match="bad parameter line"):
        scip.parse_parameters(scip.Reply(b"PP", b"00", (b"DMIN:20;5",), True))


def test_a_scan_reply_round_trips_and_a_damaged_line_is_caught() -> None:
    ranges = [20 + 7 * i for i in range(682)]
    block = scip.scan_reply(b"MD0044072501000", b"99", 123456, ranges)
    assert max(len(line) for line in block.split(b"\n")) == 65  # 64 data characters and the sum
    splitter = scip.ReplySplitter()
    blocks = []
    for i in range(0, len(block), 100):
        blocks += splitter.feed(block[i : i + 100])
    reply = scip.parse_reply(blocks[0])
    assert (reply.echo, reply.status, reply.status_sum_ok) == (b"MD0044072501000", b"99", True)
    data = scip.parse_scan(reply)
    assert data.timestamp == 123456 and data.ranges == ranges
    damaged = bytearray(blocks[0])
    damaged[40] = ord("0") if damaged[40] != ord("0") else ord("1")
    with pytest.raises(ScipError, match="checksum"):
        scip.parse_scan(scip.parse_reply(bytes(damaged)))


def test_scip_1_1_replies_have_a_bare_status() -> None:
    reply = scip.parse_reply(b"QT\nE")
    assert reply.status == b"E" and reply.lines == ()


def test_angles_come_from_the_sensor_parameters() -> None:
    assert URG_04LX.step_angle(URG_04LX.afrt) == 0.0
    assert URG_04LX.step_angle(URG_04LX.amin) == pytest.approx(-(384 - 44) * 2 * math.pi / 1024)
    assert math.degrees(URG_04LX.step_angle(URG_04LX.amax)) == pytest.approx(119.88, abs=0.01)
    assert URG_04LX.scan_time == 0.1
    parsed = scip.SensorParameters.from_pp(URG_04LX.to_pp())
    assert parsed == URG_04LX
    with pytest.raises(ScipError, match="PP reply lacks"):
        scip.SensorParameters.from_pp({"DMIN": "20"})
