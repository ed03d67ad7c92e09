"""The FT 300 wire protocol: known-answer frames, reply checks, identity, stream framing."""

from __future__ import annotations

import pytest

from hapticframe.devices import FixedFrameParser, append_crc16
from hapticframe_robotiq._protocol import (
    STREAM_FRAME_LENGTH,
    STREAM_HEADER,
    ModbusException,
    ProtocolError,
    decode_firmware,
    decode_serial_number,
    decode_stream_frame,
    decode_stream_values,
    encode_exception_reply,
    encode_firmware,
    encode_read_reply,
    encode_serial_number,
    encode_stream_frame,
    encode_write_reply,
    parse_read_reply,
    parse_request,
    parse_write_reply,
    quantise,
    read_request,
    write_request,
)


def test_known_answer_requests_of_the_notes():
    assert write_request(410, [0x0200]) == bytes.fromhex("09 10 01 9A 00 01 02 02 00 CD CA")
    assert read_request(500, 3) == bytes.fromhex("09 03 01 F4 00 03 44 8D")
    assert read_request(180, 1) == bytes.fromhex("09 03 00 B4 00 01 C5 64")
    assert read_request(180, 6) == bytes.fromhex("09 03 00 B4 00 06 84 A6")


def test_known_answer_stream_frame():
    frame = bytes.fromhex("20 4E 64 00 00 00 06 FF 00 00 00 00 D2 04 C1 A6")
    counts = decode_stream_frame(frame)
    assert counts == (100, 0, -250, 0, 0, 1234)
    force, torque = decode_stream_values(counts)
    assert force == (1.0, 0.0, -2.5)
    assert torque == (0.0, 0.0, 1.234)
    assert encode_stream_frame(quantise((1.0, 0.0, -2.5), (0.0, 0.0, 1.234))) == frame


def test_stream_frame_errors():
    frame = encode_stream_frame((1, 2, 3, 4, 5, 6))
    with pytest.raises(ProtocolError, match="CRC"):
        decode_stream_frame(frame[:-1] + bytes((frame[-1] ^ 1,)))
    with pytest.raises(ProtocolError, match="16 bytes"):
        decode_stream_frame(frame[:-1])
    with pytest.raises(ProtocolError, match="starts"):
        decode_stream_frame(append_crc16(b"\x21\x4e" + bytes(12)))


def test_quantise_rounds_and_clips_to_int16():
    assert quantise((1.004, -1.006, 400.0), (0.0004, -40.0, 0.0016)) == (
        100, -101, 32767, 0, -32768, 2,
    )


def test_read_reply_round_trip_and_every_rejection():
    reply = encode_read_reply([0x4654, 0x5303, 0x0001])
    assert parse_read_reply(reply, 3) == (0x4654, 0x5303, 0x0001)
    with pytest.raises(ProtocolError, match="slave 10"):
        parse_read_reply(encode_read_reply([1, 2, 3], slave=10), 3)
    with pytest.raises(ProtocolError, match="CRC"):
        parse_read_reply(reply[:-2] + bytes((reply[-2] ^ 0xFF, reply[-1])), 3)
    with pytest.raises(ProtocolError, match="registers"):
        parse_read_reply(reply, 2)
    with pytest.raises(ModbusException) as info:
        parse_read_reply(encode_exception_reply(0x03, 2), 3)
    assert info.value.code == 2
    assert info.value.function == 0x03
    assert "illegal data address" in str(info.value)
    with pytest.raises(ProtocolError, match="slave"):
        parse_read_reply(encode_exception_reply(0x03, 2, slave=3), 3)
    with pytest.raises(ProtocolError, match="function"):
        parse_read_reply(encode_write_reply(410, 1), 1)


def test_write_echo():
    echo = encode_write_reply(410, 1)
    assert len(echo) == 8
    parse_write_reply(echo, 410, 1)
    with pytest.raises(ProtocolError, match="registers 411"):
        parse_write_reply(encode_write_reply(411, 1), 410, 1)
    with pytest.raises(ModbusException):
        parse_write_reply(encode_exception_reply(0x10, 4), 410, 1)


def test_requests_parse_back():
    assert parse_request(read_request(500, 3)) == (9, 3, 500, (3,))
    assert parse_request(write_request(410, [0x0200])) == (9, 16, 410, (0x0200,))
    assert parse_request(write_request(410, [0x0200])[:9]) is None
    bad = bytearray(read_request(500, 3))
    bad[-1] ^= 1
    with pytest.raises(ProtocolError):
        parse_request(bytes(bad))


def test_identity_decoding():
    assert decode_firmware(encode_firmware(3, 0, 1)) == "FTS-3.0.1"
    assert decode_firmware(encode_firmware(1, 12, 255)) == "FTS-1.12.255"
    with pytest.raises(ProtocolError, match="not an FT sensor"):
        decode_firmware((0x4142, 0x4301, 0x0203))
    assert decode_serial_number(encode_serial_number("ROB", 1234)) == "ROB-1234"
    assert decode_serial_number(encode_serial_number("ABC", 7)) == "ABC-0007"
    assert decode_serial_number(encode_serial_number("ROB", 0)) == "UNKNOWN"


def _header_frames() -> list[bytes]:
    frames = [encode_stream_frame((k, -k, 3 * k, 10 * k, 0, -7)) for k in range(1, 6)]
    # Fx raw 0x4E20 (200.00 N): the payload starts with the header bytes.
    frames.insert(2, encode_stream_frame((0x4E20, 5, 6, 7, 8, 9)))
    # Across a field edge: Fy's high byte 0x20, Fz's low byte 0x4E.
    frames.insert(4, encode_stream_frame((1, 0x2011, 0x334E, 0, 0, 0)))
    return frames


def test_frames_with_header_bytes_in_their_payload():
    frames = _header_frames()
    assert STREAM_HEADER in frames[2][2:]
    assert STREAM_HEADER in frames[4][2:]
    assert decode_stream_values(decode_stream_frame(frames[2]))[0][0] == 200.0


@pytest.mark.parametrize("chunk", [1, 3, 7, 16, 1000])
def test_the_stream_parser_stays_in_sync(chunk):
    frames = _header_frames()
    # Start mid-frame (a stream the host joins late) and end with a torn frame.
    stream = frames[0][9:] + b"".join(frames) + frames[1][:10]
    parser = FixedFrameParser(STREAM_HEADER, STREAM_FRAME_LENGTH)
    got = []
    for start in range(0, len(stream), chunk):
        got += parser.feed(stream[start : start + chunk])
    assert got == frames
    assert parser.stats.frames == len(frames)


def test_a_lost_byte_costs_one_frame_and_never_a_false_one():
    frames = _header_frames()
    damaged = frames[2][:5] + frames[2][6:]  # the 200 N frame loses a byte
    parser = FixedFrameParser(STREAM_HEADER, STREAM_FRAME_LENGTH)
    got = parser.feed(b"".join(frames[:2]) + damaged + b"".join(frames[3:]))
    assert got == frames[:2] + frames[3:]
    assert parser.stats.crc_errors >= 1
