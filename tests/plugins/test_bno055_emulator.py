"""BNO055 emulator model: register file, modes and their latency, reset, timing, faults, physics."""

import math
from types import SimpleNamespace

import numpy as np
import pytest
import serial

from hapticframe.devices import FakeClock, FaultEvent, FaultSchedule, PtyEmulator
from hapticframe.geometry import rotation_matrix_from_rpy_deg, wxyz_from_rotation_matrix
from hapticframe_bno055._emulator import (
    GRAVITY_M_PER_S2,
    MODEL_FAULT_KINDS,
    Bno055Model,
    standard_faults,
)
from hapticframe_bno055._protocol import (
    DATA_LENGTH,
    DATA_START,
    OperationMode,
    Register,
    decode_data_block,
    encode_read,
    encode_write,
)

READ_DATA = encode_read(DATA_START, DATA_LENGTH)


def exchange(model, request, t, wait_s=0.01):
    model.receive(request, t)
    return model.emit(t + wait_s)


def configured(mode=OperationMode.NDOF, **kwargs):
    model = Bno055Model(**kwargs)
    assert exchange(model, encode_write(Register.UNIT_SEL, b"\x00"), 0.0) == b"\xee\x01"
    assert exchange(model, encode_write(Register.OPR_MODE, bytes((mode,))), 0.01) == b"\xee\x01"
    return model


def test_chip_id_and_reply_timing():
    model = Bno055Model()
    model.receive(encode_read(Register.CHIP_ID, 1), 1.0)
    assert model.emit(1.0) == b""  # 3 bytes at 115200 baud take 0.26 ms
    assert model.emit(1.001) == b"\xbb\x01\xa0"
    model.receive(READ_DATA, 2.0)
    assert model.emit(2.003) == b""  # 48 bytes: 4.2 ms
    assert len(model.emit(2.005)) == 2 + DATA_LENGTH


def test_config_mode_reads_zero_and_mode_switch_latency():
    model = Bno055Model()
    reply = exchange(model, READ_DATA, 0.0)
    assert reply[:2] == b"\xbb\x2e" and not any(reply[2:-2])  # CONFIG: zeros (temp, calib kept)
    assert exchange(model, encode_write(Register.OPR_MODE, b"\x0c"), 0.1, 0.001) == b"\xee\x01"
    # 7 ms CONFIG → NDOF: a read 5 ms after the write still sees CONFIG-mode zeros.
    assert not any(exchange(model, READ_DATA, 0.105, 0.005)[2:8])
    block = decode_data_block(exchange(model, READ_DATA, 0.12)[2:])
    np.testing.assert_allclose(block.acceleration_m_per_s2, [0, 0, 9.81])
    np.testing.assert_allclose(block.orientation_wxyz, [1, 0, 0, 0])
    assert model.mode(0.2) == OperationMode.NDOF
    # Back to CONFIG takes 19 ms.
    exchange(model, encode_write(Register.OPR_MODE, b"\x00"), 0.3, 0.001)
    assert model.mode(0.315) == OperationMode.NDOF
    assert model.mode(0.32) == OperationMode.CONFIG


def test_accgyro_has_no_fusion():
    model = configured(OperationMode.ACCGYRO)
    block = decode_data_block(exchange(model, READ_DATA, 0.1)[2:])
    np.testing.assert_allclose(block.acceleration_m_per_s2, [0, 0, 9.81])
    assert not block.orientation_wxyz.any() and not block.gravity_m_per_s2.any()
    np.testing.assert_array_equal(block.calibration, [0, 3, 3, 0])


def test_write_rules_and_malformed_requests():
    model = configured()
    # UNIT_SEL is writable in CONFIG mode only; data registers never.
    assert exchange(model, encode_write(Register.UNIT_SEL, b"\x00"), 0.1) == b"\xee\x05"
    assert exchange(model, encode_write(Register.ACC_DATA, b"\x00"), 0.2) == b"\xee\x05"
    assert exchange(model, bytes.fromhex("AA010800"), 0.3) == b"\xee\x09"  # length 0
    assert exchange(model, bytes.fromhex("AA017F02"), 0.4) == b"\xee\x04"  # past the map
    # A wrong start byte is dropped without an answer; the next request is served.
    assert exchange(model, b"\x55\x01\x00\x01", 0.5) == b""
    assert exchange(model, encode_read(Register.CHIP_ID, 1), 0.6) == b"\xbb\x01\xa0"


def test_inter_byte_gap_gives_receive_character_timeout():
    model = Bno055Model()
    request = encode_read(Register.CHIP_ID, 1)
    model.receive(request[:2], 1.0)
    assert model.emit(1.02) == b""
    model.receive(request[2:], 1.04)  # 40 ms after the previous byte
    assert model.emit(1.05) == b"\xee\x0a"
    assert exchange(model, request, 1.1) == b"\xbb\x01\xa0"  # the line is usable again


def test_reset_is_silent_for_650_ms_and_returns_to_config():
    model = configured()
    assert exchange(model, encode_write(Register.SYS_TRIGGER, b"\x20"), 1.0) == b""  # no ack
    assert exchange(model, encode_read(Register.CHIP_ID, 1), 1.3) == b""
    assert exchange(model, encode_read(Register.CHIP_ID, 1), 1.64) == b""
    assert exchange(model, encode_read(Register.CHIP_ID, 1), 1.66) == b"\xbb\x01\xa0"
    assert model.mode(1.7) == OperationMode.CONFIG
    assert not any(exchange(model, READ_DATA, 1.8)[2:8])


def schedule(*events, seed=0):
    return FaultSchedule(list(events), np.random.default_rng(seed))


def test_request_faults():
    faults = schedule(
        FaultEvent("bus_overrun", at_s=1.0, params={"count": 2}),
        FaultEvent("status", at_s=2.0, params={"code": 3}),
        FaultEvent("no_reply", at_s=3.0),
        FaultEvent("rx_stall", at_s=4.0),
    )
    model = configured(faults=faults)
    request = encode_read(Register.CHIP_ID, 1)
    assert exchange(model, request, 1.0) == b"\xee\x07"
    assert exchange(model, request, 1.1) == b"\xee\x07"
    assert exchange(model, request, 1.2) == b"\xbb\x01\xa0"
    assert exchange(model, request, 2.0) == b"\xee\x03"
    assert exchange(model, request, 3.0) == b""
    assert exchange(model, request, 4.0) == b""
    assert model.emit(4.04) == b"\xee\x0a"
    assert [f.kind for f in faults.injected] == ["bus_overrun", "status", "no_reply", "rx_stall"]


def test_reply_faults_are_recorded():
    faults = schedule(
        FaultEvent("partial_reply", at_s=1.0, params={"keep": 10}),
        FaultEvent("wrong_length", at_s=2.0),
        FaultEvent("stale_bytes", at_s=3.0, params={"count": 4}),
    )
    model = configured(faults=faults)
    partial = exchange(model, READ_DATA, 1.0)
    assert partial[:2] == b"\xbb\x2e" and len(partial) == 12
    assert exchange(model, READ_DATA, 2.0)[:2] == b"\xbb\x2f"
    fresh = exchange(model, READ_DATA, 2.5)
    stale = exchange(model, READ_DATA, 3.0)
    assert stale[:4] == fresh[-4:] and stale[4:6] == b"\xbb\x2e"
    assert [r.frame_fault for r in model.served[-4:]] == [
        "partial_reply", "wrong_length", None, "stale_bytes"
    ]


def test_value_faults():
    faults = schedule(
        FaultEvent("bad_quaternion", at_s=1.0, duration_s=0.1, params={"scale": 0.5}),
        FaultEvent("bad_gravity", at_s=2.0, duration_s=0.1),
        FaultEvent("calib_drop", at_s=3.0, duration_s=0.1),
    )
    model = configured(faults=faults)
    q = decode_data_block(exchange(model, READ_DATA, 1.05)[2:]).orientation_wxyz
    np.testing.assert_allclose(q, [0.5, 0, 0, 0])
    g = decode_data_block(exchange(model, READ_DATA, 2.05)[2:]).gravity_m_per_s2
    assert np.linalg.norm(g) == pytest.approx(0.7 * 9.81, abs=0.01)
    block = decode_data_block(exchange(model, READ_DATA, 3.05)[2:])
    np.testing.assert_array_equal(block.calibration, [0, 0, 0, 0])
    assert model.served[0].corrupted == ("bad_quaternion",)
    later = decode_data_block(exchange(model, READ_DATA, 3.5)[2:])
    np.testing.assert_array_equal(later.calibration, [3, 3, 3, 3])
    np.testing.assert_allclose(later.orientation_wxyz, [1, 0, 0, 0])


def test_spontaneous_reset_fault():
    model = configured(faults=schedule(FaultEvent("reset", at_s=1.0)))
    assert exchange(model, READ_DATA, 1.0) == b""
    assert model.silent(1.5) and not model.silent(1.7)
    assert model.mode(1.7) == OperationMode.CONFIG


def test_physics_follows_the_truth_and_the_mount():
    tilt = rotation_matrix_from_rpy_deg([20.0, 0.0, 0.0])  # the tool, rolled 20° in the world
    truth = SimpleNamespace(
        orientation_wxyz=wxyz_from_rotation_matrix(tilt),
        linear_acceleration_m_per_s2=np.array([1.0, 0.0, 0.0]),
        angular_velocity_rad_per_s=np.array([0.0, 0.0, 0.5]),
    )
    model = configured(truth=lambda t: truth, mount_rpy_deg=(0.0, 0.0, 90.0))
    block = decode_data_block(exchange(model, READ_DATA, 0.1)[2:])
    r_wi = tilt @ rotation_matrix_from_rpy_deg([0.0, 0.0, 90.0])
    g = np.array([0.0, 0.0, GRAVITY_M_PER_S2])
    a_w = truth.linear_acceleration_m_per_s2
    np.testing.assert_allclose(block.acceleration_m_per_s2, r_wi.T @ (a_w + g), atol=0.005)
    np.testing.assert_allclose(block.linear_acceleration_m_per_s2, r_wi.T @ a_w, atol=0.005)
    np.testing.assert_allclose(block.gravity_m_per_s2, r_wi.T @ g, atol=0.005)
    np.testing.assert_allclose(block.angular_velocity_rad_per_s, r_wi.T @ [0, 0, 0.5],
                               atol=math.radians(1 / 32))
    np.testing.assert_allclose(block.orientation_wxyz, wxyz_from_rotation_matrix(r_wi), atol=1e-4)


def test_noise_is_seeded_and_held_within_a_fusion_tick():
    def values(seed):
        model = configured(rng=np.random.default_rng(seed), accel_noise_std_m_per_s2=0.5)
        return [exchange(model, READ_DATA, t)[2:8] for t in (0.100, 0.105, 0.110)]

    first, again, other = values(1), values(1), values(2)
    assert first == again and first != other
    assert first[0] == first[1] != first[2]


def test_standard_schedule_uses_known_kinds():
    harness = {"drop_bytes", "garbage", "fragment", "stall", "disconnect"}
    kinds = {event.kind for event in standard_faults()}
    assert kinds <= set(MODEL_FAULT_KINDS) | harness
    assert set(MODEL_FAULT_KINDS) <= kinds


def test_any_serial_library_opens_the_pty():
    clock = FakeClock()
    with PtyEmulator(configured(), clock=clock) as emulator:
        port = serial.Serial(emulator.path, baudrate=115200, timeout=0)
        try:
            port.write(encode_read(Register.CHIP_ID, 1))
            port.flush()
            received = b""
            for _ in range(20):
                clock.advance(0.001)
                received += port.read(16)
                if len(received) >= 3:
                    break
            assert received == b"\xbb\x01\xa0"
        finally:
            port.close()
