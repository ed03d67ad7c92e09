"""The Robotiq FT 300 wire protocol: Modbus RTU requests and replies, and stream frames.

Pure functions, no I/O. The sensor talks Modbus RTU (19200 8N1, slave 9) until register 410
is set to 0x0200; from then on it streams 16-byte frames at 100 Hz::

    0x20 0x4E | Fx Fy Fz Mx My Mz (int16, little-endian) | CRC-16/Modbus (low byte first)

Forces are in 1/100 N, torques in 1/1000 N·m. Modbus registers are big-endian on the wire.
Streaming has no stop command: the host sends 0xFF bytes until the sensor falls silent
(:data:`JAM_BYTES`).
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from hapticframe.devices import append_crc16, check_crc16

__all__ = [
    "EXCEPTION_REPLY_LENGTH",
    "FORCE_COUNTS_PER_N",
    "FUNCTION_READ_HOLDING",
    "FUNCTION_WRITE_MULTIPLE",
    "JAM_BYTES",
    "ProtocolError",
    "ModbusException",
    "REGISTER_FIRMWARE",
    "REGISTER_FORCE_TORQUE",
    "REGISTER_OUTPUT_MODE",
    "REGISTER_PRODUCTION_YEAR",
    "REGISTER_SERIAL_NUMBER",
    "SLAVE_ID",
    "STREAM_FRAME_LENGTH",
    "STREAM_HEADER",
    "STREAM_MODE_VALUE",
    "TORQUE_COUNTS_PER_NM",
    "WRITE_REPLY_LENGTH",
    "DeviceInfo",
    "decode_firmware",
    "decode_serial_number",
    "decode_stream_frame",
    "decode_stream_values",
    "encode_exception_reply",
    "encode_firmware",
    "encode_read_reply",
    "encode_serial_number",
    "encode_stream_frame",
    "encode_write_reply",
    "parse_read_reply",
    "parse_request",
    "parse_write_reply",
    "quantise",
    "read_reply_length",
    "read_request",
    "reply_length",
    "write_request",
]

SLAVE_ID = 9
FUNCTION_READ_HOLDING = 0x03
FUNCTION_WRITE_MULTIPLE = 0x10
#: Fx, Fy, Fz, Mx, My, Mz: six registers.
REGISTER_FORCE_TORQUE = 180
#: 'F','T','S', major, minor, patch: three registers.
REGISTER_FIRMWARE = 500
#: Three ASCII characters and a 32-bit number: four registers.
REGISTER_SERIAL_NUMBER = 510
REGISTER_PRODUCTION_YEAR = 514
#: Writing :data:`STREAM_MODE_VALUE` here starts streaming.
REGISTER_OUTPUT_MODE = 410
STREAM_MODE_VALUE = 0x0200

STREAM_HEADER = b"\x20\x4e"
STREAM_FRAME_LENGTH = 16
FORCE_COUNTS_PER_N = 100.0
TORQUE_COUNTS_PER_NM = 1000.0
#: One burst of the stream-stopping "jam" (the manual: 0xFF for about half a second).
JAM_BYTES = b"\xff" * 50

WRITE_REPLY_LENGTH = 8
EXCEPTION_REPLY_LENGTH = 5
_MAX_READ_REGISTERS = 125

_STREAM = struct.Struct("<2s6h")


class ProtocolError(ValueError):
    """A reply or frame that breaks the protocol (bad CRC, wrong slave, wrong layout)."""


class ModbusException(ProtocolError):
    """The device answered a request with a Modbus exception (function | 0x80).

    Parameters
    ----------
    function : int
        The function code of the request.
    code : int
        The exception code (1 illegal function, 2 illegal data address, 3 illegal value...).
    """

    def __init__(self, function: int, code: int) -> None:
        self.function = function
        self.code = code
        super().__init__(f"Modbus exception {code} ({_EXCEPTION_NAMES.get(code, 'unknown')}) "
                         f"in reply to function 0x{function:02X}")


_EXCEPTION_NAMES = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "slave device failure",
}


def _check_register(value: int, what: str) -> None:
    if not 0 <= value <= 0xFFFF:
        raise ValueError(f"{what} must be in 0..65535, got {value}")


# --- requests (host → sensor) ---------------------------------------------------------------


def read_request(first_register: int, count: int, *, slave: int = SLAVE_ID) -> bytes:
    """A function 03 (read holding registers) request, CRC included."""
    _check_register(first_register, "first_register")
    if not 1 <= count <= _MAX_READ_REGISTERS:
        raise ValueError(f"count must be in 1..{_MAX_READ_REGISTERS}, got {count}")
    return append_crc16(struct.pack(">BBHH", slave, FUNCTION_READ_HOLDING, first_register, count))


def write_request(first_register: int, values: Sequence[int], *, slave: int = SLAVE_ID) -> bytes:
    """A function 16 (preset multiple registers) request, CRC included."""
    _check_register(first_register, "first_register")
    if not 1 <= len(values) <= 123:
        raise ValueError(f"write 1..123 registers, got {len(values)}")
    for value in values:
        _check_register(value, "register value")
    head = struct.pack(
        ">BBHHB", slave, FUNCTION_WRITE_MULTIPLE, first_register, len(values), 2 * len(values)
    )
    return append_crc16(head + struct.pack(f">{len(values)}H", *values))


def parse_request(frame: bytes) -> tuple[int, int, int, tuple[int, ...]] | None:
    """Decode a complete request at the start of ``frame`` (the emulator's side).

    Returns
    -------
    (slave, function, first_register, values_or_count) or None
        For function 03 the last item is ``(count,)``; for 16 the written values. None when
        ``frame`` holds too few bytes for the request it begins (wait for more).

    Raises
    ------
    ProtocolError
        A bad CRC, or a function code other than 03 or 16 (the caller answers it with
        exception 1 after checking the CRC over the first 8 bytes).
    """
    if len(frame) < 8:
        return None
    slave, function = frame[0], frame[1]
    if function == FUNCTION_READ_HOLDING:
        if not check_crc16(frame[:8]):
            raise ProtocolError("request with a bad CRC")
        first, count = struct.unpack_from(">HH", frame, 2)
        return slave, function, first, (count,)
    if function == FUNCTION_WRITE_MULTIPLE:
        if len(frame) < 7:
            return None
        n_bytes = frame[6]
        length = 7 + n_bytes + 2
        if len(frame) < length:
            return None
        if not check_crc16(frame[:length]):
            raise ProtocolError("request with a bad CRC")
        first, count = struct.unpack_from(">HH", frame, 2)
        if n_bytes != 2 * count:
            raise ProtocolError(f"write of {count} registers announces {n_bytes} bytes")
        values = struct.unpack_from(f">{count}H", frame, 7)
        return slave, function, first, tuple(values)
    raise ProtocolError(f"unsupported function 0x{function:02X}")


# --- replies (sensor → host) ----------------------------------------------------------------


def read_reply_length(count: int) -> int:
    """Bytes in a function 03 reply carrying ``count`` registers."""
    return 5 + 2 * count


def reply_length(head: bytes | bytearray, expected: int) -> int | None:
    """Length of the reply that ``head`` begins: an exception reply, or ``expected``.

    None when fewer than two bytes are there to tell.
    """
    if len(head) < 2:
        return None
    return EXCEPTION_REPLY_LENGTH if head[1] & 0x80 else expected


def _check_reply(reply: bytes, function: int, slave: int) -> None:
    if len(reply) < EXCEPTION_REPLY_LENGTH:
        raise ProtocolError(f"reply of {len(reply)} bytes is too short")
    if reply[1] & 0x80 and len(reply) == EXCEPTION_REPLY_LENGTH:
        if not check_crc16(reply):
            raise ProtocolError("exception reply with a bad CRC")
        if reply[0] != slave:
            raise ProtocolError(f"exception reply from slave {reply[0]}, expected {slave}")
        raise ModbusException(reply[1] & 0x7F, reply[2])
    if not check_crc16(reply):
        raise ProtocolError(f"reply with a bad CRC: {reply.hex(' ')}")
    if reply[0] != slave:
        raise ProtocolError(f"reply from slave {reply[0]}, expected {slave}")
    if reply[1] != function:
        raise ProtocolError(f"reply to function 0x{reply[1]:02X}, expected 0x{function:02X}")


def parse_read_reply(reply: bytes, count: int, *, slave: int = SLAVE_ID) -> tuple[int, ...]:
    """The register values (unsigned) of a function 03 reply.

    Raises
    ------
    ModbusException
        The device answered with an exception reply.
    ProtocolError
        A bad CRC, another slave id, another function, or a length that does not match.
    """
    _check_reply(reply, FUNCTION_READ_HOLDING, slave)
    if len(reply) != read_reply_length(count) or reply[2] != 2 * count:
        raise ProtocolError(
            f"read reply of {len(reply)} bytes announcing {reply[2]}; expected {2 * count} "
            f"data bytes for {count} registers"
        )
    return struct.unpack_from(f">{count}H", reply, 3)


def parse_write_reply(
    reply: bytes, first_register: int, count: int, *, slave: int = SLAVE_ID
) -> None:
    """Check a function 16 echo (slave, function, first register, count, CRC).

    Raises
    ------
    ModbusException, ProtocolError
        As :func:`parse_read_reply`, or an echo of another register range.
    """
    _check_reply(reply, FUNCTION_WRITE_MULTIPLE, slave)
    if len(reply) != WRITE_REPLY_LENGTH:
        raise ProtocolError(f"write echo of {len(reply)} bytes, expected {WRITE_REPLY_LENGTH}")
    first, n = struct.unpack_from(">HH", reply, 2)
    if (first, n) != (first_register, count):
        raise ProtocolError(
            f"write echo for registers {first}+{n}, expected {first_register}+{count}"
        )


def encode_read_reply(values: Sequence[int], *, slave: int = SLAVE_ID) -> bytes:
    """A function 03 reply carrying ``values`` (unsigned 16-bit)."""
    data = struct.pack(f">{len(values)}H", *values)
    return append_crc16(bytes((slave, FUNCTION_READ_HOLDING, len(data))) + data)


def encode_write_reply(first_register: int, count: int, *, slave: int = SLAVE_ID) -> bytes:
    """The echo of a function 16 request."""
    return append_crc16(
        struct.pack(">BBHH", slave, FUNCTION_WRITE_MULTIPLE, first_register, count)
    )


def encode_exception_reply(function: int, code: int, *, slave: int = SLAVE_ID) -> bytes:
    """An exception reply (function | 0x80, code)."""
    return append_crc16(bytes((slave, (function | 0x80) & 0xFF, code)))


# --- identity -------------------------------------------------------------------------------


@dataclass(frozen=True)
class DeviceInfo:
    """What identifies a sensor: firmware ``"FTS-a.b.c"``, serial ``"XXX-NNNN"``, year."""

    firmware: str
    serial_number: str
    production_year: int


def _register_bytes(registers: Sequence[int]) -> bytes:
    return struct.pack(f">{len(registers)}H", *registers)


def decode_firmware(registers: Sequence[int]) -> str:
    """Registers 500-502 as ``"FTS-a.b.c"``.

    Raises
    ------
    ProtocolError
        When the first character is not ``'F'`` (the identity check the official driver
        applies during port discovery) or the prefix is not printable ASCII.
    """
    if len(registers) != 3:
        raise ValueError(f"firmware needs 3 registers, got {len(registers)}")
    raw = _register_bytes(registers)
    prefix = raw[:3]
    if prefix[:1] != b"F" or not all(0x20 <= b < 0x7F for b in prefix):
        raise ProtocolError(f"not an FT sensor: firmware registers read {raw.hex(' ')}")
    return f"{prefix.decode('ascii')}-{raw[3]}.{raw[4]}.{raw[5]}"


def encode_firmware(major: int, minor: int, patch: int, prefix: bytes = b"FTS") -> tuple[int, ...]:
    """Registers 500-502 for a firmware version."""
    raw = prefix + bytes((major, minor, patch))
    return struct.unpack(">3H", raw)


def decode_serial_number(registers: Sequence[int]) -> str:
    """Registers 510-513 as ``"XXX-NNNN"`` (``"UNKNOWN"`` when the number is 0).

    The three characters are register 510's high and low bytes and register 511's high
    byte; the number is the 32-bit big-endian value of registers 512-513.
    """
    if len(registers) != 4:
        raise ValueError(f"the serial number needs 4 registers, got {len(registers)}")
    raw = _register_bytes(registers)
    number = struct.unpack_from(">I", raw, 4)[0]
    if number == 0:
        return "UNKNOWN"
    letters = raw[:3].decode("ascii", errors="replace")
    return f"{letters}-{number:04d}"


def encode_serial_number(letters: str, number: int) -> tuple[int, ...]:
    """Registers 510-513 for a serial number such as ``("ROB", 1234)``."""
    raw = letters.encode("ascii")[:3].ljust(3, b"\0") + b"\0" + struct.pack(">I", number)
    return struct.unpack(">4H", raw)


# --- stream frames --------------------------------------------------------------------------


def quantise(force_n: Iterable[float], torque_nm: Iterable[float]) -> tuple[int, ...]:
    """Six int16 counts of a wrench (rounded; clipped to the int16 range)."""
    counts = [round(f * FORCE_COUNTS_PER_N) for f in force_n]
    counts += [round(m * TORQUE_COUNTS_PER_NM) for m in torque_nm]
    return tuple(max(-32768, min(32767, c)) for c in counts)


def encode_stream_frame(counts: Sequence[int]) -> bytes:
    """A 16-byte stream frame from six int16 counts (forces in 1/100 N, torques in 1/1000 N·m)."""
    if len(counts) != 6:
        raise ValueError(f"a stream frame holds 6 values, got {len(counts)}")
    return append_crc16(_STREAM.pack(STREAM_HEADER, *counts))


def decode_stream_frame(frame: bytes) -> tuple[int, ...]:
    """The six int16 counts of a stream frame.

    Raises
    ------
    ProtocolError
        Wrong length, wrong header or bad CRC.
    """
    if len(frame) != STREAM_FRAME_LENGTH:
        raise ProtocolError(f"a stream frame has {STREAM_FRAME_LENGTH} bytes, got {len(frame)}")
    if frame[:2] != STREAM_HEADER:
        raise ProtocolError(f"stream frame starts {frame[:2].hex(' ')}, not 20 4e")
    if not check_crc16(frame):
        raise ProtocolError(f"stream frame with a bad CRC: {frame.hex(' ')}")
    return tuple(_STREAM.unpack_from(frame)[1:])


def decode_stream_values(counts: Sequence[int]) -> tuple[tuple[float, float, float],
                                                          tuple[float, float, float]]:
    """Force (N) and torque (N·m) of six counts."""
    fx, fy, fz, mx, my, mz = counts
    return (
        (fx / FORCE_COUNTS_PER_N, fy / FORCE_COUNTS_PER_N, fz / FORCE_COUNTS_PER_N),
        (mx / TORQUE_COUNTS_PER_NM, my / TORQUE_COUNTS_PER_NM, mz / TORQUE_COUNTS_PER_NM),
    )
