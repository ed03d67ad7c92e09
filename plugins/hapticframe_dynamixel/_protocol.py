"""Dynamixel Protocol 2.0 packets: CRC, byte stuffing, instruction and status packets.

Pure functions and one incremental parser, no I/O. The wire format (e-manual "Protocol 2.0";
``dynamixel_sdk/protocol2_packet_handler.py``)::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | params... | CRC_L CRC_H

``LEN`` counts INST, the (stuffed) parameters and the CRC. A status packet has INST 0x55 and
an ERR byte before its parameters. The CRC is CRC-16/BUYPASS (polynomial 0x8005, initial 0,
not reflected) over everything from the first 0xFF to the last parameter *after* byte
stuffing: a receiver checks the CRC first and then removes the stuffing (the SDK's order).
Byte stuffing inserts an extra 0xFD wherever FF FF FD occurs in INST and parameters, so that
a header never appears inside a packet.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field

__all__ = [
    "BROADCAST_ID",
    "ERROR_NAMES",
    "ERR_ACCESS",
    "ERR_ALERT",
    "ERR_CRC",
    "ERR_DATA_LENGTH",
    "ERR_DATA_LIMIT",
    "ERR_DATA_RANGE",
    "ERR_INSTRUCTION",
    "ERR_RESULT_FAIL",
    "HEADER",
    "INST_BULK_READ",
    "INST_PING",
    "INST_READ",
    "INST_REBOOT",
    "INST_STATUS",
    "INST_SYNC_READ",
    "INST_SYNC_WRITE",
    "INST_WRITE",
    "MAX_ID",
    "MAX_PACKET_LENGTH",
    "InstructionPacket",
    "PacketParser",
    "ParserCounters",
    "ProtocolError",
    "StatusPacket",
    "bulk_read_packet",
    "crc16_dxl",
    "decode_instruction",
    "decode_status",
    "encode_instruction",
    "encode_status",
    "error_name",
    "ping_packet",
    "read_packet",
    "reboot_packet",
    "stuff",
    "sync_read_packet",
    "sync_write_packet",
    "unstuff",
    "write_packet",
]

HEADER = b"\xff\xff\xfd\x00"
_PREFIX = b"\xff\xff\xfd"
#: The largest unicast ID; 0xFE is the broadcast ID.
MAX_ID = 252
BROADCAST_ID = 0xFE
#: The SDK refuses a status packet whose LEN field exceeds this (``RXPACKET_MAX_LEN``).
MAX_PACKET_LENGTH = 1024

INST_PING = 0x01
INST_READ = 0x02
INST_WRITE = 0x03
INST_REBOOT = 0x08
INST_STATUS = 0x55
INST_SYNC_READ = 0x82
INST_SYNC_WRITE = 0x83
INST_BULK_READ = 0x92

#: Bit 7 of the status ERR byte: a hardware error is latched (Hardware Error Status, reg 70).
ERR_ALERT = 0x80
ERR_RESULT_FAIL = 1
ERR_INSTRUCTION = 2
ERR_CRC = 3
ERR_DATA_RANGE = 4
ERR_DATA_LENGTH = 5
ERR_DATA_LIMIT = 6
ERR_ACCESS = 7

#: The error numbers of bits 0-6 of the ERR byte.
ERROR_NAMES: Mapping[int, str] = {
    0: "ok",
    ERR_RESULT_FAIL: "result fail",
    ERR_INSTRUCTION: "instruction error",
    ERR_CRC: "CRC error",
    ERR_DATA_RANGE: "data range error",
    ERR_DATA_LENGTH: "data length error",
    ERR_DATA_LIMIT: "data limit error",
    ERR_ACCESS: "access error",
}


class ProtocolError(ValueError):
    """A packet that is not a valid Protocol 2.0 packet of the expected kind."""


def _crc_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16_dxl(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16/BUYPASS of ``data`` (poly 0x8005, init 0, MSB first); ``b"123456789"`` → 0xFEE8."""
    for byte in bytes(data):
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]) & 0xFFFF
    return crc


def error_name(error: int) -> str:
    """A status ERR byte in words: ``"data range error"``, ``"access error, alert"``."""
    number = error & 0x7F
    name = ERROR_NAMES.get(number, f"unknown error {number}")
    if error & ERR_ALERT:
        return "alert" if number == 0 else f"{name}, alert"
    return name


def stuff(body: bytes) -> bytes:
    """Insert 0xFD after every FF FF FD of ``body`` (INST and parameters)."""
    if _PREFIX not in body:
        return bytes(body)
    out = bytearray()
    for i, byte in enumerate(body):
        out.append(byte)
        if byte == 0xFD and i >= 2 and body[i - 2] == 0xFF and body[i - 1] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Remove the 0xFD that :func:`stuff` inserted (FF FF FD FD → FF FF FD)."""
    if _PREFIX not in body:
        return bytes(body)
    out = bytearray()
    i = 0
    while i < len(body):
        byte = body[i]
        out.append(byte)
        if byte == 0xFD and i >= 2 and body[i - 2] == 0xFF and body[i - 1] == 0xFF:
            if i + 1 < len(body) and body[i + 1] == 0xFD:
                i += 1  # the stuffed byte
        i += 1
    return bytes(out)


def _frame(packet_id: int, body: bytes) -> bytes:
    stuffed = stuff(body)
    length = len(stuffed) + 2
    if length > MAX_PACKET_LENGTH:
        raise ProtocolError(f"packet too long: LEN {length} > {MAX_PACKET_LENGTH}")
    head = HEADER + bytes((packet_id, length & 0xFF, length >> 8))
    packet = head + stuffed
    crc = crc16_dxl(packet)
    return packet + bytes((crc & 0xFF, crc >> 8))


def encode_instruction(packet_id: int, instruction: int, params: bytes = b"") -> bytes:
    """An instruction packet (stuffed, with CRC)."""
    if not (0 <= packet_id <= MAX_ID or packet_id == BROADCAST_ID):
        raise ProtocolError(f"invalid ID {packet_id}")
    if instruction == INST_STATUS or not 0 <= instruction <= 0xFF:
        raise ProtocolError(f"invalid instruction 0x{instruction:02X}")
    return _frame(packet_id, bytes((instruction,)) + bytes(params))


def encode_status(packet_id: int, error: int = 0, params: bytes = b"") -> bytes:
    """A status packet (stuffed, with CRC): ERR byte then ``params``."""
    if not 0 <= packet_id <= MAX_ID:
        raise ProtocolError(f"invalid status ID {packet_id}")
    return _frame(packet_id, bytes((INST_STATUS, error & 0xFF)) + bytes(params))


def _u16(value: int) -> bytes:
    return int(value).to_bytes(2, "little")


def ping_packet(packet_id: int) -> bytes:
    """PING (0x01): the reply carries the model number (2 bytes) and firmware version."""
    return encode_instruction(packet_id, INST_PING)


def read_packet(packet_id: int, address: int, length: int) -> bytes:
    """READ (0x02) of ``length`` bytes from ``address``."""
    return encode_instruction(packet_id, INST_READ, _u16(address) + _u16(length))


def write_packet(packet_id: int, address: int, data: bytes) -> bytes:
    """WRITE (0x03) of ``data`` at ``address``."""
    return encode_instruction(packet_id, INST_WRITE, _u16(address) + bytes(data))


def reboot_packet(packet_id: int) -> bytes:
    """REBOOT (0x08): the servo answers, then restarts (clears a latched hardware error)."""
    return encode_instruction(packet_id, INST_REBOOT)


def sync_read_packet(address: int, length: int, ids: Sequence[int]) -> bytes:
    """SYNC_READ (0x82, broadcast): each listed servo answers with its own status, in order."""
    return encode_instruction(
        BROADCAST_ID, INST_SYNC_READ, _u16(address) + _u16(length) + bytes(ids)
    )


def bulk_read_packet(entries: Sequence[tuple[int, int, int]]) -> bytes:
    """BULK_READ (0x92, broadcast): ``(id, address, length)`` per servo, each ID once; each
    servo answers with its own status, in the order listed."""
    ids = [servo_id for servo_id, _, _ in entries]
    if len(set(ids)) != len(ids):
        raise ProtocolError(f"a bulk read lists a servo twice: {ids}")
    params = bytearray()
    for servo_id, address, length in entries:
        params.append(servo_id)
        params += _u16(address) + _u16(length)
    return encode_instruction(BROADCAST_ID, INST_BULK_READ, bytes(params))


def sync_write_packet(address: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """SYNC_WRITE (0x83, broadcast, no reply): ``data[id]`` (``length`` bytes) per servo."""
    params = bytearray(_u16(address) + _u16(length))
    for servo_id, chunk in data.items():
        if len(chunk) != length:
            raise ProtocolError(f"servo {servo_id}: {len(chunk)} bytes, expected {length}")
        params.append(servo_id)
        params += chunk
    return encode_instruction(BROADCAST_ID, INST_SYNC_WRITE, bytes(params))


@dataclass(frozen=True)
class InstructionPacket:
    """A decoded instruction packet (parameters unstuffed)."""

    id: int
    instruction: int
    params: bytes


@dataclass(frozen=True)
class StatusPacket:
    """A decoded status packet (parameters unstuffed)."""

    id: int
    error: int
    params: bytes

    @property
    def alert(self) -> bool:
        """Bit 7 of ERR: the servo has a hardware error latched."""
        return bool(self.error & ERR_ALERT)

    @property
    def error_number(self) -> int:
        """Bits 0-6 of ERR (0: no error)."""
        return self.error & 0x7F

    @property
    def error_name(self) -> str:
        return error_name(self.error)


def _check_frame(frame: bytes) -> tuple[int, bytes]:
    """(ID, unstuffed body) of a whole packet after the header, length and CRC checks."""
    if len(frame) < 10 or frame[:4] != HEADER:
        raise ProtocolError("not a Protocol 2.0 packet (header FF FF FD 00)")
    length = frame[5] | (frame[6] << 8)
    if len(frame) != length + 7:
        raise ProtocolError(f"LEN {length} does not match {len(frame)} bytes")
    crc = frame[-2] | (frame[-1] << 8)
    if crc16_dxl(frame[:-2]) != crc:
        raise ProtocolError("CRC mismatch")
    return frame[4], unstuff(frame[7:-2])


def decode_status(frame: bytes) -> StatusPacket:
    """A whole status packet, CRC checked before unstuffing.

    Raises
    ------
    ProtocolError
        For a bad header, length or CRC, or an instruction other than 0x55.
    """
    packet_id, body = _check_frame(bytes(frame))
    if len(body) < 2 or body[0] != INST_STATUS:
        raise ProtocolError("not a status packet (INST 0x55 and ERR)")
    return StatusPacket(packet_id, body[1], bytes(body[2:]))


def decode_instruction(frame: bytes) -> InstructionPacket:
    """A whole instruction packet, CRC checked before unstuffing."""
    packet_id, body = _check_frame(bytes(frame))
    if not body or body[0] == INST_STATUS:
        raise ProtocolError("not an instruction packet")
    return InstructionPacket(packet_id, body[0], bytes(body[1:]))


@dataclass
class ParserCounters:
    """What a :class:`PacketParser` saw: packets, CRC errors, bytes skipped to resync."""

    bytes: int = 0
    packets: int = 0
    crc_errors: int = 0
    resyncs: int = 0
    bad_headers: int = 0


@dataclass
class PacketParser:
    """Incremental Protocol 2.0 parser: feed any split of the stream, get whole packets.

    Resynchronises as ``dynamixel_sdk``'s ``rxPacket``: leading bytes before FF FF FD (not
    followed by FD) are dropped; a header whose reserved byte is not 0, whose ID is invalid,
    whose LEN exceeds :data:`MAX_PACKET_LENGTH` or whose instruction is of the wrong kind
    (0x55 for ``status=True``, anything else otherwise) loses one byte and the scan goes on.
    The CRC is checked before unstuffing; where the SDK gives up on a CRC mismatch
    (``COMM_RX_CORRUPT``), a stream parser drops one byte and rescans, so a half packet
    before a good one costs only the half packet.

    Parameters
    ----------
    status : bool
        Parse status packets (device → host) or instruction packets (host → device).
    """

    status: bool = True
    counters: ParserCounters = field(default_factory=ParserCounters)
    _buffer: bytearray = field(default_factory=bytearray, repr=False)

    def clear(self) -> None:
        """Forget a partial packet (after a flush or a reconnect)."""
        self._buffer.clear()

    @property
    def pending(self) -> int:
        """Bytes held for an incomplete packet."""
        return len(self._buffer)

    def _skip(self, count: int) -> None:
        del self._buffer[:count]
        self.counters.resyncs += count

    def feed(self, data: Iterable[int] | bytes) -> list[StatusPacket | InstructionPacket]:
        """Every complete valid packet in the stream so far, in order."""
        chunk = bytes(data)
        self.counters.bytes += len(chunk)
        buf = self._buffer
        buf += chunk
        out: list[StatusPacket | InstructionPacket] = []
        while True:
            start = self._find_header()
            if start is None:
                # Keep a possible header start (up to FF FF FD) at the end.
                keep = 0
                for n in (3, 2, 1):
                    if len(buf) >= n and buf[-n:] == _PREFIX[:n]:
                        keep = n
                        break
                if len(buf) > keep:
                    self._skip(len(buf) - keep)
                return out
            if start:
                self._skip(start)
            if len(buf) < 8:
                return out
            length = buf[5] | (buf[6] << 8)
            inst = buf[7]
            bad_id = buf[4] > MAX_ID if self.status else not (
                buf[4] <= MAX_ID or buf[4] == BROADCAST_ID
            )
            bad_inst = inst != INST_STATUS if self.status else inst == INST_STATUS
            if buf[3] != 0 or bad_id or length > MAX_PACKET_LENGTH or length < 3 or bad_inst:
                self.counters.bad_headers += 1
                self._skip(1)
                continue
            total = length + 7
            if len(buf) < total:
                return out
            frame = bytes(buf[:total])
            try:
                packet: StatusPacket | InstructionPacket = (
                    decode_status(frame) if self.status else decode_instruction(frame)
                )
            except ProtocolError:
                self.counters.crc_errors += 1
                self._skip(1)
                continue
            del buf[:total]
            self.counters.packets += 1
            out.append(packet)

    def _find_header(self) -> int | None:
        buf = self._buffer
        index = buf.find(_PREFIX)
        while index >= 0:
            if index + 3 >= len(buf) or buf[index + 3] != 0xFD:
                return index
            index = buf.find(_PREFIX, index + 1)
        return None
