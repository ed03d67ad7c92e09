"""Incremental framing: bytes arrive split and merged arbitrarily; frames come out whole.

A serial line (a USB adapter, a pseudo-terminal) delivers whatever has arrived, so one read is
never one frame. These parsers keep a buffer between calls and return only complete frames.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from hapticframe.devices._crc import check_crc16

__all__ = ["FixedFrameParser", "LineFramer", "ParserStats"]


@dataclass
class ParserStats:
    """What a parser has seen, for health telemetry.

    Attributes
    ----------
    bytes : int
        Bytes fed.
    frames : int
        Valid frames (or lines) returned.
    crc_errors : int
        Candidate frames whose check failed.
    resyncs : int
        Bytes skipped while hunting a header (after a failed check, or noise between frames).
    overflows : int
        Times data were discarded because a buffer limit was reached (an over-long line, or
        more unread bytes than the parser may hold).
    """

    bytes: int = 0
    frames: int = 0
    crc_errors: int = 0
    resyncs: int = 0
    overflows: int = 0


class FixedFrameParser:
    """Fixed-length frames that start with a header and end with a check (a CRC).

    The parser scans for the header; a candidate whose check fails counts a CRC error and the
    scan moves on by ONE byte, so header bytes that happen to occur inside a payload never
    cost a real frame more than once, and the stream resynchronises on the next true frame.

    Parameters
    ----------
    header : bytes
        The constant bytes every frame starts with (at least one).
    length : int
        The whole frame's length, header and check included.
    check : callable, optional
        Validates a candidate frame (default: the last two bytes are its CRC-16/Modbus).
    max_buffer : int, optional
        Most bytes held between calls; when one call brings more, the oldest are dropped (an
        overflow: a reader that fell behind gets the newest data, as a UART's FIFO would).

    Examples
    --------
    >>> from hapticframe.devices import FixedFrameParser, append_crc16
    >>> frame = append_crc16(b"\\x20\\x4e" + bytes(12))
    >>> parser = FixedFrameParser(b"\\x20\\x4e", 16)
    >>> parser.feed(b"\\x00" + frame[:5]), parser.feed(frame[5:]) == [frame]
    ([], True)
    """

    def __init__(
        self,
        header: bytes,
        length: int,
        *,
        check: Callable[[bytes], bool] = check_crc16,
        max_buffer: int = 4096,
    ) -> None:
        if not header:
            raise ValueError("header must have at least one byte")
        if length < len(header):
            raise ValueError(f"length {length} is shorter than the header")
        if max_buffer < length:
            raise ValueError(f"max_buffer {max_buffer} cannot hold one frame of {length} bytes")
        self.header = bytes(header)
        self.length = length
        self.check = check
        self.max_buffer = max_buffer
        self.stats = ParserStats()
        self._buffer = bytearray()

    @property
    def buffered(self) -> int:
        """Bytes held for the next call (a partial frame)."""
        return len(self._buffer)

    def reset(self) -> None:
        """Forget buffered bytes (after a reconnect); the statistics are kept."""
        self._buffer.clear()

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes and return every complete valid frame, in order."""
        stats = self.stats
        stats.bytes += len(data)
        buffer = self._buffer
        buffer += data
        excess = len(buffer) - self.max_buffer
        if excess > 0:
            del buffer[:excess]
            stats.overflows += 1
        header, length, check = self.header, self.length, self.check
        frames: list[bytes] = []
        position = 0
        end = len(buffer)
        while True:
            start = buffer.find(header, position)
            if start < 0:
                # Keep a tail that may be the start of a header split across reads.
                keep = min(len(header) - 1, end - position)
                while keep and not header.startswith(buffer[end - keep : end]):
                    keep -= 1
                stats.resyncs += end - keep - position
                position = end - keep
                break
            stats.resyncs += start - position
            position = start
            if end - start < length:
                break
            candidate = bytes(buffer[start : start + length])
            if check(candidate):
                frames.append(candidate)
                position = start + length
            else:
                stats.crc_errors += 1
                stats.resyncs += 1
                position = start + 1
        del buffer[:position]
        stats.frames += len(frames)
        return frames


class LineFramer:
    """Delimited lines (ASCII devices, NMEA, a lab's own firmware).

    Parameters
    ----------
    delimiter : bytes, optional
        What ends a line (not included in the lines returned).
    max_length : int, optional
        Longest line kept. A longer one is noise: it is discarded up to its delimiter and
        counted in ``stats.overflows``.
    """

    def __init__(self, delimiter: bytes = b"\n", *, max_length: int = 1024) -> None:
        if not delimiter:
            raise ValueError("delimiter must have at least one byte")
        if max_length < 1:
            raise ValueError("max_length must be positive")
        self.delimiter = bytes(delimiter)
        self.max_length = max_length
        self.stats = ParserStats()
        self._buffer = bytearray()
        self._discarding = False  # inside an over-long line: drop until its delimiter

    @property
    def buffered(self) -> int:
        """Bytes of an incomplete line held for the next call."""
        return len(self._buffer)

    def reset(self) -> None:
        """Forget an incomplete line; the statistics are kept."""
        self._buffer.clear()
        self._discarding = False

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes and return the complete lines, without their delimiter."""
        self.stats.bytes += len(data)
        self._buffer += data
        delimiter = self.delimiter
        lines: list[bytes] = []
        position = 0
        while True:
            end = self._buffer.find(delimiter, position)
            if end < 0:
                break
            if self._discarding:
                self._discarding = False
            elif end - position > self.max_length:
                self.stats.overflows += 1
            else:
                lines.append(bytes(self._buffer[position:end]))
            position = end + len(delimiter)
        del self._buffer[:position]
        # An incomplete line already too long can never be kept: drop it now, bounding the
        # buffer (a delimiter split across reads is kept whole).
        keep = len(delimiter) - 1
        if len(self._buffer) > self.max_length + keep:
            if not self._discarding:
                self.stats.overflows += 1
                self._discarding = True
            del self._buffer[: len(self._buffer) - keep]
        self.stats.frames += len(lines)
        return lines
