"""Serial protocol: CRC, COBS, frame round trips, and a parser that survives anything."""
import os
import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from lhd_hw_bridge.protocol import (MAX_ENCODED, CommandFrame, FrameParser, HeartbeatFrame, ProtocolError, SensorFrame,
                                    cobs_decode, cobs_encode, crc16, crc16_ccitt, decode_packet, encode)

SENSOR = SensorFrame(123456, -0.3141, 0.7, -0.191, 0.2, 2.7, 2.65, 2.5, 3.2, 3.1, 6.0, 1, 0, 1)
SENSOR_Q = decode_packet(cobs_decode(encode(SENSOR, 0)[:-1]))[1]  # as quantised on the wire


def test_crc_check_value():
    assert crc16_ccitt(b"123456789") == 0x29B1
    assert crc16(b"123456789") == 0x29B1
    data = os.urandom(300)
    assert crc16(data) == crc16_ccitt(data)


@pytest.mark.parametrize("n", [0, 1, 2, 253, 254, 255, 256, 509, 600])
def test_cobs_round_trip_has_no_zero(n):
    rng = random.Random(n)
    for data in (bytes(n), bytes(rng.randrange(256) for _ in range(n)), b"\x01" * n):
        enc = cobs_encode(data)
        assert b"\x00" not in enc
        assert cobs_decode(enc) == data


def test_cobs_known_vectors():
    # from the COBS paper / Wikipedia examples
    assert cobs_encode(b"\x00") == b"\x01\x01"
    assert cobs_encode(b"\x00\x00") == b"\x01\x01\x01"
    assert cobs_encode(b"\x11\x22\x00\x33") == b"\x03\x11\x22\x02\x33"
    assert cobs_encode(b"\x11\x22\x33\x44") == b"\x05\x11\x22\x33\x44"


def test_frames_round_trip_with_their_scales():
    p = FrameParser()
    wire = encode(SENSOR, 5) + encode(CommandFrame(2.7, 1, 0, True), 9) + encode(HeartbeatFrame(4242), 1)
    (s1, f1), (s2, f2), (s3, f3) = p.feed(wire)
    assert (s1, s2, s3) == (5, 9, 1)
    assert f1.boom_angle == pytest.approx(-0.3141, abs=1e-4) and f1.wheel_fl == pytest.approx(2.7, abs=1e-3)
    assert f1.current_rear == pytest.approx(6.0, abs=1e-3) and f1.valve_boom == 1 and f1.flags == 1
    assert f2 == CommandFrame(2.7, 1, 0, True)
    assert f3 == HeartbeatFrame(4242)
    assert len(encode(SENSOR, 0)) <= MAX_ENCODED


def test_out_of_range_fields_are_refused_when_encoding():
    with pytest.raises(ProtocolError, match="wheel_setpoint"):
        encode(CommandFrame(40.0, 0, 0, True), 0)
    with pytest.raises(ProtocolError, match="valve_boom"):
        encode(CommandFrame(1.0, 2, 0, True), 0)


def test_garbage_truncated_and_bad_crc_frames_resynchronise():
    p = FrameParser()
    good = encode(SENSOR, 1)
    bad_crc = bytearray(good)
    bad_crc[5] ^= 0x40
    truncated = good[: len(good) // 2]
    noise = bytes(random.Random(1).randrange(1, 256) for _ in range(500))  # no delimiter: overflow path
    stream = b"\x00\x00" + truncated + b"\x00" + bytes(bad_crc) + noise + b"\x00" + good + good
    out = p.feed(stream)
    assert [m for _, m in out] == [SENSOR_Q, SENSOR_Q]
    assert p.crc_errors + p.framing_errors >= 2 and p.overflows >= 1
    assert p.buffered == 0


def test_frames_split_at_every_byte_boundary():
    wire = encode(SENSOR, 3) + encode(CommandFrame(1.0, 0, 1, True), 4)
    for cut in range(len(wire) + 1):
        p = FrameParser()
        out = p.feed(wire[:cut]) + p.feed(wire[cut:])
        assert len(out) == 2


def test_sequence_gaps_are_counted():
    p = FrameParser()
    p.feed(encode(SENSOR, 1) + encode(SENSOR, 2) + encode(SENSOR, 5))
    assert p.frames == 3 and p.seq_gaps == 1


def test_decode_packet_errors_name_the_fault():
    with pytest.raises(ProtocolError, match="short"):
        decode_packet(b"\x01\x02")
    body = bytes([2, 1, 0, 0])
    with pytest.raises(ProtocolError, match="version"):
        decode_packet(body + crc16(body).to_bytes(2, "little"))


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=2000))
def test_parser_never_raises_and_stays_bounded(data):
    p = FrameParser()
    p.feed(data)
    assert p.buffered <= MAX_ENCODED
    # and it still decodes a good frame afterwards
    out = p.feed(b"\x00" + encode(SENSOR, 7))
    assert out and out[-1][1] == SENSOR_Q


@settings(max_examples=200, deadline=None)
@given(st.lists(st.binary(max_size=100), max_size=30), st.integers(0, 255))
def test_good_frames_survive_interleaved_garbage(chunks, seq):
    frame = encode(CommandFrame(1.5, 1, 1, True), seq)
    stream = b"".join(c.replace(b"\x00", b"") + b"\x00" + frame for c in chunks)
    p = FrameParser()
    got = [m for _, m in p.feed(stream)]
    assert got.count(CommandFrame(1.5, 1, 1, True)) >= len(chunks) - sum(1 for c in chunks if len(c) > MAX_ENCODED)
