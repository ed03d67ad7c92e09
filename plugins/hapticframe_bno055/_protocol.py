"""The BNO055 UART protocol: request and reply frames, the register map and SI decoding.

Pure functions only (no I/O, no clock): the driver and the emulator share them.

Frames (datasheet §4.7)::

    write request   0xAA 0x00 reg n data[n]      → 0xEE status (0x01 = written)
    read request    0xAA 0x01 reg n              → 0xBB n data[n]   or   0xEE status

Data registers, page 0, default units (UNIT_SEL = 0: m/s², deg/s): accelerometer 0x08,
gyroscope 0x14 (16 LSB per deg/s), quaternion 0x20 (2^14 LSB per unit), linear acceleration
0x28 and gravity 0x2E (100 LSB per m/s²), temperature 0x34 (int8 °C) and CALIB_STAT 0x35.
One burst read of 46 bytes from 0x08 to 0x35 covers all of them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "ACCEL_LSB_PER_M_PER_S2",
    "CHIP_ID_VALUE",
    "DATA_LENGTH",
    "DATA_START",
    "GYRO_LSB_PER_DPS",
    "GYRO_LSB_PER_RPS",
    "MAX_PAYLOAD",
    "QUATERNION_LSB",
    "READ_REPLY",
    "REQUEST_START",
    "RETRYABLE_STATUSES",
    "STATUS_REPLY",
    "SYS_TRIGGER_RESET",
    "UNIT_SEL_SI",
    "DataBlock",
    "OperationMode",
    "Register",
    "Reply",
    "Status",
    "decode_calibration",
    "decode_data_block",
    "encode_calibration",
    "encode_data_block",
    "encode_read",
    "encode_read_reply",
    "encode_status",
    "encode_write",
    "fusion_mode",
    "parse_reply",
    "status_name",
]

REQUEST_START = 0xAA
READ_REPLY = 0xBB
STATUS_REPLY = 0xEE
_WRITE = 0x00
_READ = 0x01
#: The most data bytes one request or reply may carry.
MAX_PAYLOAD = 128
CHIP_ID_VALUE = 0xA0
#: SYS_TRIGGER bit that resets the chip (never acknowledged in UART mode).
SYS_TRIGGER_RESET = 0x20

ACCEL_LSB_PER_M_PER_S2 = 100.0
GYRO_LSB_PER_DPS = 16.0
GYRO_LSB_PER_RPS = 900.0
QUATERNION_LSB = float(1 << 14)
#: UNIT_SEL the driver writes: m/s², deg/s (converted to rad/s on decoding), degrees, °C,
#: Windows orientation. deg/s keeps the gyroscope's 1/16 dps resolution (rad/s would give
#: 1/900 rad/s = 0.064 dps per LSB, four times coarser).
UNIT_SEL_SI = 0x00


class Register(IntEnum):
    """Page-0 register addresses."""

    CHIP_ID = 0x00
    PAGE_ID = 0x07
    ACC_DATA = 0x08
    MAG_DATA = 0x0E
    GYR_DATA = 0x14
    EUL_DATA = 0x1A
    QUA_DATA = 0x20
    LIA_DATA = 0x28
    GRV_DATA = 0x2E
    TEMP = 0x34
    CALIB_STAT = 0x35
    SYS_STATUS = 0x39
    SYS_ERR = 0x3A
    UNIT_SEL = 0x3B
    OPR_MODE = 0x3D
    PWR_MODE = 0x3E
    SYS_TRIGGER = 0x3F


class OperationMode(IntEnum):
    """OPR_MODE values (low nibble)."""

    CONFIG = 0x00
    ACCONLY = 0x01
    MAGONLY = 0x02
    GYROONLY = 0x03
    ACCMAG = 0x04
    ACCGYRO = 0x05
    MAGGYRO = 0x06
    AMG = 0x07
    IMU = 0x08
    COMPASS = 0x09
    M4G = 0x0A
    NDOF_FMC_OFF = 0x0B
    NDOF = 0x0C


def fusion_mode(mode: int) -> bool:
    """True for the modes that compute orientation, gravity and linear acceleration."""
    return mode >= OperationMode.IMU


class Status(IntEnum):
    """The status byte after 0xEE."""

    WRITE_SUCCESS = 0x01
    READ_FAIL = 0x02
    WRITE_FAIL = 0x03
    REGMAP_INVALID_ADDRESS = 0x04
    REGMAP_WRITE_DISABLED = 0x05
    WRONG_START_BYTE = 0x06
    BUS_OVER_RUN_ERROR = 0x07
    MAX_LENGTH_ERROR = 0x08
    MIN_LENGTH_ERROR = 0x09
    RECEIVE_CHARACTER_TIMEOUT = 0x0A


#: Statuses the application note says to answer by resending the command.
RETRYABLE_STATUSES = frozenset({Status.BUS_OVER_RUN_ERROR, Status.RECEIVE_CHARACTER_TIMEOUT})

DATA_START = Register.ACC_DATA
#: Bytes from ACC_DATA (0x08) to CALIB_STAT (0x35) inclusive.
DATA_LENGTH = Register.CALIB_STAT - Register.ACC_DATA + 1


def status_name(code: int) -> str:
    """The datasheet's name of a status code (``"0x2A"`` style for unknown ones)."""
    try:
        return Status(code).name
    except ValueError:
        return f"UNKNOWN_STATUS_0x{code:02X}"


def _check_register(register: int, length: int) -> None:
    if not 0 <= register <= 0x7F:
        raise ValueError(f"register 0x{register:X} is outside page 0 (0x00..0x7F)")
    if not 1 <= length <= MAX_PAYLOAD:
        raise ValueError(f"length {length} must be 1..{MAX_PAYLOAD}")


def encode_write(register: int, data: bytes) -> bytes:
    """The request that writes ``data`` to consecutive registers from ``register``."""
    _check_register(register, len(data))
    return bytes((REQUEST_START, _WRITE, register, len(data))) + bytes(data)


def encode_read(register: int, length: int) -> bytes:
    """The request that reads ``length`` consecutive registers from ``register``."""
    _check_register(register, length)
    return bytes((REQUEST_START, _READ, register, length))


def encode_read_reply(data: bytes) -> bytes:
    """The device's successful read reply (``0xBB n data``)."""
    if not 1 <= len(data) <= MAX_PAYLOAD:
        raise ValueError(f"a read reply carries 1..{MAX_PAYLOAD} bytes, got {len(data)}")
    return bytes((READ_REPLY, len(data))) + bytes(data)


def encode_status(code: int) -> bytes:
    """The device's status reply (``0xEE code``)."""
    return bytes((STATUS_REPLY, code & 0xFF))


@dataclass(frozen=True)
class Reply:
    """One parsed reply.

    Exactly one of ``data`` (a 0xBB read reply), ``status`` (a 0xEE reply) and ``error``
    is set. ``error`` says why the bytes are no reply the driver may use:

    - ``"wrong_start"``: the first byte is neither 0xBB nor 0xEE (garbage or a stale tail);
    - ``"wrong_length"``: a read reply whose length byte is not the length requested;
    - ``"trailing_bytes"``: more bytes than the reply holds (stale or garbage bytes: the
      frame cannot be trusted, since the protocol has no checksum).
    """

    data: bytes | None = None
    status: int | None = None
    error: str | None = None


def parse_reply(buffer: bytes, expected_length: int | None) -> Reply | None:
    """Parse the bytes received since a request was sent.

    Parameters
    ----------
    buffer : bytes
        Everything received since the input was flushed and the request written.
    expected_length : int or None
        The length of the read request, or None after a write (only 0xEE is valid then).

    Returns
    -------
    Reply or None
        None while the reply is incomplete (wait for more bytes); otherwise the reply or
        the reason it is unusable. A reply is accepted only when the buffer holds exactly
        its bytes: a stale or garbage byte before or after it rejects the exchange.
    """
    if not buffer:
        return None
    start = buffer[0]
    if start == STATUS_REPLY:
        if len(buffer) < 2:
            return None
        if len(buffer) > 2:
            return Reply(error="trailing_bytes")
        return Reply(status=buffer[1])
    if start != READ_REPLY or expected_length is None:
        return Reply(error="wrong_start")
    if len(buffer) < 2:
        return None
    if buffer[1] != expected_length:
        return Reply(error="wrong_length")
    size = 2 + expected_length
    if len(buffer) < size:
        return None
    if len(buffer) > size:
        return Reply(error="trailing_bytes")
    return Reply(data=bytes(buffer[2:]))


@dataclass(frozen=True)
class DataBlock:
    """The data registers 0x08..0x35 in SI units.

    Attributes
    ----------
    acceleration_m_per_s2 : (3,)
        Raw accelerometer (specific force: gravity included).
    angular_velocity_rad_per_s : (3,)
    orientation_wxyz : (4,)
        The fused quaternion as read (not renormalised: the driver checks its norm).
    linear_acceleration_m_per_s2 : (3,)
    gravity_m_per_s2 : (3,)
    temperature_c : float
    calibration : (4,)
        Levels 0..3 of the system, gyroscope, accelerometer and magnetometer.
    """

    acceleration_m_per_s2: NDArray[np.float64]
    angular_velocity_rad_per_s: NDArray[np.float64]
    orientation_wxyz: NDArray[np.float64]
    linear_acceleration_m_per_s2: NDArray[np.float64]
    gravity_m_per_s2: NDArray[np.float64]
    temperature_c: float
    calibration: NDArray[np.float64]


def _int16s(data: bytes, register: int, count: int) -> NDArray[np.float64]:
    offset = register - DATA_START
    raw = np.frombuffer(data, dtype="<i2", count=count, offset=offset)
    return raw.astype(np.float64)


def decode_calibration(stat: int) -> NDArray[np.float64]:
    """CALIB_STAT → levels (sys, gyro, accel, mag), each 0..3."""
    return np.array(
        [(stat >> 6) & 3, (stat >> 4) & 3, (stat >> 2) & 3, stat & 3], dtype=np.float64
    )


def encode_calibration(levels: tuple[int, int, int, int]) -> int:
    """Levels (sys, gyro, accel, mag) → CALIB_STAT."""
    sys_, gyro, accel, mag = (min(max(int(v), 0), 3) for v in levels)
    return (sys_ << 6) | (gyro << 4) | (accel << 2) | mag


def decode_data_block(data: bytes, unit_sel: int = UNIT_SEL_SI) -> DataBlock:
    """Decode a burst read of the 46 data bytes 0x08..0x35 into SI units.

    ``unit_sel`` is the UNIT_SEL the device was given: bit 0 (accelerations in mg) and
    bit 1 (angular rate in rad/s) change the scales.

    Raises
    ------
    ValueError
        If ``data`` is not exactly :data:`DATA_LENGTH` bytes.
    """
    if len(data) != DATA_LENGTH:
        raise ValueError(f"a data block is {DATA_LENGTH} bytes, got {len(data)}")
    accel_scale = 1.0 / ACCEL_LSB_PER_M_PER_S2
    if unit_sel & 0x01:  # mg: 1 LSB = 1 mg
        accel_scale = 9.80665e-3
    if unit_sel & 0x02:
        gyro_scale = 1.0 / GYRO_LSB_PER_RPS
    else:
        gyro_scale = math.pi / 180.0 / GYRO_LSB_PER_DPS
    temp = data[Register.TEMP - DATA_START]
    return DataBlock(
        acceleration_m_per_s2=_int16s(data, Register.ACC_DATA, 3) * accel_scale,
        angular_velocity_rad_per_s=_int16s(data, Register.GYR_DATA, 3) * gyro_scale,
        orientation_wxyz=_int16s(data, Register.QUA_DATA, 4) / QUATERNION_LSB,
        linear_acceleration_m_per_s2=_int16s(data, Register.LIA_DATA, 3) * accel_scale,
        gravity_m_per_s2=_int16s(data, Register.GRV_DATA, 3) * accel_scale,
        temperature_c=float(temp - 256 if temp > 127 else temp),
        calibration=decode_calibration(data[Register.CALIB_STAT - DATA_START]),
    )


def _to_int16(values: NDArray[np.float64], scale: float) -> NDArray[np.int16]:
    raw = np.rint(np.asarray(values, dtype=np.float64) * scale)
    return np.clip(raw, -32768, 32767).astype(np.int16)


def encode_data_block(
    *,
    acceleration_m_per_s2: NDArray[np.float64],
    angular_velocity_rad_per_s: NDArray[np.float64],
    orientation_wxyz: NDArray[np.float64],
    linear_acceleration_m_per_s2: NDArray[np.float64],
    gravity_m_per_s2: NDArray[np.float64],
    temperature_c: float = 25.0,
    calibration_stat: int = 0xFF,
    unit_sel: int = UNIT_SEL_SI,
) -> bytes:
    """The 46 register bytes 0x08..0x35 for SI values (int16 rounding and saturation).

    The magnetometer (0x0E) and Euler angles (0x1A) are left zero: the driver reads past them.
    """
    accel_scale = ACCEL_LSB_PER_M_PER_S2 if not unit_sel & 0x01 else 1.0 / 9.80665e-3
    gyro_scale = (
        GYRO_LSB_PER_RPS if unit_sel & 0x02 else GYRO_LSB_PER_DPS * 180.0 / math.pi
    )
    block = bytearray(DATA_LENGTH)

    def put(register: int, raw: NDArray[np.int16]) -> None:
        offset = register - DATA_START
        block[offset : offset + 2 * raw.size] = raw.astype("<i2").tobytes()

    put(Register.ACC_DATA, _to_int16(acceleration_m_per_s2, accel_scale))
    put(Register.GYR_DATA, _to_int16(angular_velocity_rad_per_s, gyro_scale))
    put(Register.QUA_DATA, _to_int16(orientation_wxyz, QUATERNION_LSB))
    put(Register.LIA_DATA, _to_int16(linear_acceleration_m_per_s2, accel_scale))
    put(Register.GRV_DATA, _to_int16(gravity_m_per_s2, accel_scale))
    block[Register.TEMP - DATA_START] = int(np.clip(round(temperature_c), -128, 127)) & 0xFF
    block[Register.CALIB_STAT - DATA_START] = calibration_stat & 0xFF
    return bytes(block)
