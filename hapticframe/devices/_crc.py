"""CRC-16/Modbus: the checksum of Modbus RTU frames and of many sensors' stream frames."""

from __future__ import annotations

__all__ = ["append_crc16", "check_crc16", "crc16_modbus"]


def _table() -> tuple[int, ...]:
    # One entry per byte value: the reflected polynomial 0xA001 applied eight times.
    rows = []
    for value in range(256):
        crc = value
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
        rows.append(crc)
    return tuple(rows)


_TABLE = _table()


def crc16_modbus(data: bytes, crc: int = 0xFFFF) -> int:
    """CRC-16/Modbus of ``data``.

    Reflected polynomial 0xA001, initial value 0xFFFF, no final xor; ``b"123456789"`` gives
    0x4B37.

    Parameters
    ----------
    data : bytes
        The bytes to check.
    crc : int, optional
        The running value, to continue a CRC over several pieces.

    Returns
    -------
    int
        The 16-bit CRC.
    """
    table = _TABLE
    for byte in data:
        crc = (crc >> 8) ^ table[(crc ^ byte) & 0xFF]
    return crc


def append_crc16(payload: bytes) -> bytes:
    """``payload`` followed by its CRC-16/Modbus, low byte first (the Modbus wire order)."""
    crc = crc16_modbus(payload)
    return bytes(payload) + bytes((crc & 0xFF, crc >> 8))


def check_crc16(frame: bytes) -> bool:
    """Whether the last two bytes of ``frame`` are the CRC-16/Modbus of the rest (low first)."""
    if len(frame) < 3:
        return False
    crc = crc16_modbus(frame[:-2])
    return frame[-2] == crc & 0xFF and frame[-1] == crc >> 8
