"""BNO055 protocol core: request and reply frames, statuses, data-block decoding (known answers)."""

import math

import numpy as np
import pytest

from hapticframe_bno055._protocol import (
    DATA_LENGTH,
    DATA_START,
    RETRYABLE_STATUSES,
    Register,
    Reply,
    Status,
    decode_calibration,
    decode_data_block,
    encode_calibration,
    encode_data_block,
    encode_read,
    encode_read_reply,
    encode_status,
    encode_write,
    parse_reply,
    status_name,
)


def test_requests_known_bytes():
    assert encode_write(Register.OPR_MODE, b"\x0c") == bytes.fromhex("AA003D010C")
    assert encode_read(Register.CHIP_ID, 1) == bytes.fromhex("AA010001")
    assert encode_read(DATA_START, DATA_LENGTH) == bytes.fromhex("AA01082E")
    assert DATA_LENGTH == 46
    with pytest.raises(ValueError, match="length"):
        encode_read(0x08, 0)
    with pytest.raises(ValueError, match="length"):
        encode_write(0x08, bytes(129))
    with pytest.raises(ValueError, match="page 0"):
        encode_read(0x80, 1)


def test_replies_and_status_names():
    assert encode_read_reply(b"\xa0") == bytes.fromhex("BB01A0")
    assert encode_status(Status.BUS_OVER_RUN_ERROR) == bytes.fromhex("EE07")
    assert status_name(0x07) == "BUS_OVER_RUN_ERROR"
    assert status_name(0x0A) == "RECEIVE_CHARACTER_TIMEOUT"
    assert status_name(0x01) == "WRITE_SUCCESS"
    assert status_name(0x42) == "UNKNOWN_STATUS_0x42"
    assert RETRYABLE_STATUSES == {0x07, 0x0A}


@pytest.mark.parametrize(
    ("buffer", "expected_length", "reply"),
    [
        (b"", 1, None),
        (b"\xbb", 1, None),
        (b"\xbb\x01", 1, None),
        (b"\xbb\x01\xa0", 1, Reply(data=b"\xa0")),
        (b"\xee", 1, None),
        (b"\xee\x07", 1, Reply(status=7)),
        (b"\xee\x01", None, Reply(status=1)),
        (b"\xbb\x02\xa0\x00", 1, Reply(error="wrong_length")),
        (b"\xbb\x01\xa0\x00", 1, Reply(error="trailing_bytes")),
        (b"\xee\x01\xbb", None, Reply(error="trailing_bytes")),
        (b"\x2e\xbb\x01\xa0", 1, Reply(error="wrong_start")),
        (b"\xbb\x01\xa0", None, Reply(error="wrong_start")),  # a data reply to a write
    ],
)
def test_parse_reply(buffer, expected_length, reply):
    assert parse_reply(buffer, expected_length) == reply


def _block(**words):
    data = bytearray(DATA_LENGTH)
    for register, values in words.items():
        offset = Register[register] - DATA_START
        raw = np.asarray(values, dtype="<i2").tobytes()
        data[offset : offset + len(raw)] = raw
    return data


def test_decode_known_block():
    data = _block(
        ACC_DATA=[100, -250, 981], GYR_DATA=[16, -32, 0], QUA_DATA=[16384, 0, -8192, 0],
        LIA_DATA=[1, 2, -3], GRV_DATA=[0, 0, 981],
    )
    data[Register.TEMP - DATA_START] = 0xE7  # int8 -25 °C
    data[Register.CALIB_STAT - DATA_START] = 0b11_10_01_00
    block = decode_data_block(bytes(data))
    np.testing.assert_array_equal(block.acceleration_m_per_s2, [1.0, -2.5, 9.81])
    np.testing.assert_allclose(
        block.angular_velocity_rad_per_s, [math.pi / 180, -2 * math.pi / 180, 0.0]
    )
    np.testing.assert_array_equal(block.orientation_wxyz, [1.0, 0.0, -0.5, 0.0])
    np.testing.assert_array_equal(block.linear_acceleration_m_per_s2, [0.01, 0.02, -0.03])
    np.testing.assert_array_equal(block.gravity_m_per_s2, [0.0, 0.0, 9.81])
    assert block.temperature_c == -25.0
    np.testing.assert_array_equal(block.calibration, [3, 2, 1, 0])
    with pytest.raises(ValueError, match="46 bytes"):
        decode_data_block(bytes(45))


def test_other_units_and_calibration_codes():
    data = _block(ACC_DATA=[1000, 0, 0], GYR_DATA=[900, 0, 0])
    block = decode_data_block(bytes(data), unit_sel=0x03)  # mg and rad/s
    assert block.acceleration_m_per_s2[0] == pytest.approx(9.80665)
    assert block.angular_velocity_rad_per_s[0] == pytest.approx(1.0)
    assert encode_calibration((3, 2, 1, 0)) == 0xE4
    np.testing.assert_array_equal(decode_calibration(0xFF), [3, 3, 3, 3])


def test_encode_decode_round_trip_quantises_and_saturates():
    rng = np.random.default_rng(3)
    accel = rng.normal(0, 5, 3)
    gyro = rng.normal(0, 1, 3)
    quat = rng.normal(size=4)
    quat /= np.linalg.norm(quat)
    data = encode_data_block(
        acceleration_m_per_s2=accel, angular_velocity_rad_per_s=gyro, orientation_wxyz=quat,
        linear_acceleration_m_per_s2=np.array([400.0, -400.0, 0.0]),  # beyond ±327.67
        gravity_m_per_s2=np.array([0.0, 0.0, 9.80665]), calibration_stat=0x3C,
    )
    block = decode_data_block(data)
    np.testing.assert_allclose(block.acceleration_m_per_s2, accel, atol=0.005 + 1e-12)
    np.testing.assert_allclose(
        block.angular_velocity_rad_per_s, gyro, atol=math.radians(1 / 32) + 1e-12
    )
    np.testing.assert_allclose(block.orientation_wxyz, quat, atol=0.5 / 16384 + 1e-12)
    np.testing.assert_array_equal(block.linear_acceleration_m_per_s2, [327.67, -327.68, 0.0])
    np.testing.assert_array_equal(block.calibration, [0, 3, 3, 0])
