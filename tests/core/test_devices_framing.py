"""CRC-16/Modbus known answers and the incremental parsers of hapticframe.devices."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from hapticframe.devices import (
    FixedFrameParser,
    LineFramer,
    append_crc16,
    check_crc16,
    crc16_modbus,
)

HEADER = b"\x20\x4e"

# Modbus frames of the FT300 notes (§1.1), CRC low byte first, and the stream example (§1.2).
KNOWN_FRAMES = [
    "09 03 00 B4 00 01 C5 64",
    "09 03 00 B4 00 06 84 A6",
    "09 10 01 9A 00 01 02 02 00 CD CA",
    "09 03 01 F4 00 03 44 8D",
    "20 4E 64 00 00 00 06 FF 00 00 00 00 D2 04 C1 A6",
]


def test_crc_check_value():
    assert crc16_modbus(b"123456789") == 0x4B37
    # Continuing a running CRC over pieces equals the CRC of the whole.
    assert crc16_modbus(b"56789", crc16_modbus(b"1234")) == 0x4B37


@pytest.mark.parametrize("frame", KNOWN_FRAMES)
def test_crc_known_frames(frame):
    raw = bytes.fromhex(frame)
    assert append_crc16(raw[:-2]) == raw
    assert check_crc16(raw)
    corrupted = bytearray(raw)
    corrupted[2] ^= 0x01
    assert not check_crc16(bytes(corrupted))


def _frame(values: tuple[int, ...]) -> bytes:
    return append_crc16(HEADER + np.array(values, dtype="<i2").tobytes())


def _frames(n: int, seed: int = 0) -> list[bytes]:
    rng = np.random.default_rng(seed)
    return [_frame(tuple(int(v) for v in rng.integers(-2000, 2000, 6))) for _ in range(n)]


def test_fixed_parser_returns_frames_in_order_and_counts_them():
    frames = _frames(5)
    parser = FixedFrameParser(HEADER, 16)
    assert parser.feed(b"".join(frames)) == frames
    assert (parser.stats.frames, parser.stats.bytes, parser.stats.crc_errors) == (5, 80, 0)
    assert parser.buffered == 0


def test_a_bad_crc_costs_one_frame_and_resyncs_by_one_byte():
    good = _frames(3)
    bad = bytearray(good[1])
    bad[5] ^= 0xFF
    parser = FixedFrameParser(HEADER, 16)
    assert parser.feed(good[0] + bytes(bad) + good[2]) == [good[0], good[2]]
    assert parser.stats.crc_errors == 1
    assert parser.stats.resyncs == 16  # the bad frame's bytes, skipped one at a time


def test_a_header_inside_a_payload_never_costs_the_real_frame():
    # Fx raw 0x4E20 is "20 4E" on the wire: a false header inside the payload.
    tricky = _frame((0x4E20, 0x4E20, 0, 0x204E, 1, 2))
    before, after = _frames(2, seed=3)
    parser = FixedFrameParser(HEADER, 16)
    # Starting mid-frame puts the parser on the false header first: it costs a CRC error,
    # then the true frames that follow are all delivered.
    out = parser.feed(tricky[2:] + before + tricky + after)
    assert out == [before, tricky, after]
    assert parser.stats.crc_errors >= 1


def test_fragmentation_does_not_change_the_frames():
    frames = _frames(40, seed=1)
    frames[7] = _frame((0x4E20, 0x204E, 0x4E20, 0, 0, 0))
    stream = b"".join(frames)
    whole = FixedFrameParser(HEADER, 16).feed(stream)
    rng = np.random.default_rng(7)
    for _ in range(20):
        parser = FixedFrameParser(HEADER, 16)
        cuts = np.sort(rng.integers(0, len(stream), size=int(rng.integers(1, 60))))
        out = []
        for piece in np.split(np.frombuffer(stream, np.uint8), cuts):
            out += parser.feed(piece.tobytes())
        assert out == whole == frames
        assert parser.stats.bytes == len(stream)


def test_garbage_between_frames_is_skipped_and_counted():
    frames = _frames(3, seed=2)
    noise = [b"\xff\x20", b"\x00\x20\x4e\x01", b"junk"]
    parser = FixedFrameParser(HEADER, 16)
    stream = frames[0] + noise[0] + frames[1] + noise[1] + noise[2] + frames[2]
    assert parser.feed(stream) == frames
    stats = parser.stats
    # Every byte is either in a delivered frame or counted as skipped.
    assert stats.resyncs == len(stream) - 48 and stats.crc_errors >= 1


def test_the_buffer_is_bounded():
    parser = FixedFrameParser(HEADER, 16, max_buffer=64)
    for _ in range(100):  # a long run of noise with header fragments
        assert parser.feed(b"\x20" * 7 + b"\x4e\x00" * 9) == []
        assert parser.buffered < 16
    # One feed larger than the buffer keeps the newest bytes, with an overflow counted.
    frames = _frames(10)
    out = parser.feed(b"".join(frames))
    assert out == frames[-4:] and parser.stats.overflows == 1
    parser.reset()
    assert parser.buffered == 0
    with pytest.raises(ValueError, match="max_buffer"):
        FixedFrameParser(HEADER, 16, max_buffer=8)


def test_a_custom_check_replaces_the_crc():
    parser = FixedFrameParser(b"\xaa", 4, check=lambda f: sum(f[1:3]) % 256 == f[3])
    assert parser.feed(b"\xaa\x01\x02\x03\xaa\x01\x02\x04\xaa\x05\x05\x0a") == [
        b"\xaa\x01\x02\x03", b"\xaa\x05\x05\x0a"
    ]
    assert parser.stats.crc_errors == 1


def test_line_framer_splits_and_joins_reads():
    framer = LineFramer()
    assert framer.feed(b"12\n3") == [b"12"]
    assert framer.feed(b"4\n\n56") == [b"34", b""]
    assert framer.buffered == 2
    crlf = LineFramer(b"\r\n")
    assert crlf.feed(b"a\r") == [] and crlf.feed(b"\nb\r\n") == [b"a", b"b"]


def test_line_framer_discards_over_long_lines():
    framer = LineFramer(max_length=8)
    assert framer.feed(b"ok\n" + b"x" * 20) == [b"ok"]
    assert framer.buffered <= 8 and framer.stats.overflows == 1
    assert framer.feed(b"y" * 30) == []  # still the same over-long line: counted once
    assert framer.stats.overflows == 1 and framer.buffered <= 8
    assert framer.feed(b"zz\nnext\n") == [b"next"]  # the rest of it is dropped, then lines
    assert framer.feed(b"0123456789\n12345678\n") == [b"12345678"]
    assert framer.stats.overflows == 2 and framer.stats.frames == 3


def test_importing_the_toolkit_does_not_import_pyserial():
    code = (
        "import sys, hapticframe.devices as d\n"
        "d.SerialTransport('loop://', baudrate=9600)\n"
        "print('serial' in sys.modules)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=60, check=True)
    assert proc.stdout.strip() == "False"
