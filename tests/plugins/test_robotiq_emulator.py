"""The emulated FT 300: its Modbus side, its stream pacing and jam, and its physics."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from hapticframe.devices import FaultSchedule, FixedFrameParser
from hapticframe_robotiq._emulator import (
    STANDARD_FAULTS,
    STANDARD_GRAVITY_M_PER_S2,
    Ft300Model,
    Ft300Physics,
    wrench_from_truth,
)
from hapticframe_robotiq._protocol import (
    JAM_BYTES,
    STREAM_FRAME_LENGTH,
    STREAM_HEADER,
    ModbusException,
    decode_firmware,
    decode_serial_number,
    decode_stream_frame,
    parse_read_reply,
    parse_write_reply,
    read_request,
    write_request,
)


@dataclass(frozen=True)
class Truth:
    orientation_wxyz: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0)
    linear_acceleration_m_per_s2: tuple[float, ...] = (0.0, 0.0, 0.0)
    force_n: tuple[float, ...] = (0.0, 0.0, 0.0)
    torque_nm: tuple[float, ...] = (0.0, 0.0, 0.0)
    end_effector_mass_kg: float = 0.0


def _model(**kwargs) -> Ft300Model:
    return Ft300Model(rng=np.random.default_rng(0), **kwargs)


def _ask(model: Ft300Model, request: bytes, now: float) -> bytes:
    model.receive(request, now)
    return model.emit(now + 0.01)


def test_modbus_identity_registers():
    model = _model(firmware=(2, 1, 7), serial_number=("XYZ", 4321), production_year=2021)
    reply = _ask(model, read_request(500, 3), 0.0)
    assert decode_firmware(parse_read_reply(reply, 3)) == "FTS-2.1.7"
    registers = parse_read_reply(_ask(model, read_request(510, 5), 0.1), 5)
    assert decode_serial_number(registers[:4]) == "XYZ-4321"
    assert registers[4] == 2021


def test_modbus_reads_the_current_wrench_and_refuses_unknown_registers():
    model = _model(truth=lambda t: Truth(force_n=(1.5, -2.0, 0.0), torque_nm=(0, 0, 0.25)))
    registers = parse_read_reply(_ask(model, read_request(180, 6), 0.0), 6)
    signed = [r - 0x10000 if r & 0x8000 else r for r in registers]
    assert signed == [150, -200, 0, 0, 0, 250]
    with pytest.raises(ModbusException) as info:
        parse_read_reply(_ask(model, read_request(300, 2), 0.1), 2)
    assert info.value.code == 2


def test_requests_to_another_slave_are_ignored():
    model = _model()
    assert _ask(model, read_request(500, 3, slave=5), 0.0) == b""
    assert model.stats["requests"] == 0


def test_stream_starts_at_100_hz_and_a_jam_stops_it():
    model = _model()
    echo = _ask(model, write_request(410, [0x0200]), 0.0)
    parse_write_reply(echo[:8], 410, 1)
    assert model.streaming
    parser = FixedFrameParser(STREAM_HEADER, STREAM_FRAME_LENGTH)
    frames = parser.feed(echo[8:])
    for k in range(1, 101):
        frames += parser.feed(model.emit(0.01 + k * 0.01))
    assert 99 <= len(frames) <= 102  # one second of frames, paced by the clock
    assert len(model.sent) == len(frames)
    model.receive(JAM_BYTES[:30], 1.05)
    assert model.streaming  # fewer than 50 0xFF bytes do not stop it
    model.receive(JAM_BYTES, 1.06)
    assert not model.streaming
    model.emit(1.07)
    assert model.emit(1.5) == b""
    # Modbus answers again after the jam.
    assert decode_firmware(parse_read_reply(_ask(model, read_request(500, 3), 1.6), 3))


def test_boot_streaming_and_partial_jam_are_faults_of_the_schedule():
    schedule = FaultSchedule.from_config(
        [{"kind": "boots_streaming", "at_s": 0.0}, {"kind": "partial_jam", "at_s": 0.0}],
        np.random.default_rng(1),
    )
    model = _model(faults=schedule)
    assert model.emit(0.0) == b""  # boots (streaming) at its first service
    assert len(model.emit(0.1)) >= 9 * STREAM_FRAME_LENGTH
    model.receive(JAM_BYTES, 0.2)
    assert model.streaming and model.stats["ignored_jams"] == 1
    model.receive(JAM_BYTES, 0.3)
    assert not model.streaming and model.stats["jams"] == 1


def test_standard_schedule_is_valid():
    schedule = FaultSchedule.from_config(STANDARD_FAULTS, np.random.default_rng(0))
    assert {"bad_crc", "stall", "stream_stop"} <= schedule.kinds


def _quat_about_x(angle: float) -> tuple[float, ...]:
    return (np.cos(angle / 2), np.sin(angle / 2), 0.0, 0.0)


def test_physics_load_at_rest_reads_plus_m_g_along_tool_z():
    force, torque = wrench_from_truth(Truth(end_effector_mass_kg=0.8), Ft300Physics())
    np.testing.assert_allclose(force, [0, 0, 0.8 * STANDARD_GRAVITY_M_PER_S2])
    np.testing.assert_allclose(torque, 0)


def test_physics_rotation_acceleration_offset_and_lever_arm():
    # Tool rotated +90° about world x: world z is tool -y... the load turns with it.
    truth = Truth(
        orientation_wxyz=_quat_about_x(np.pi / 2),
        linear_acceleration_m_per_s2=(2.0, 0.0, 0.0),
        force_n=(0.0, 0.0, 5.0),
        torque_nm=(0.0, 1.0, 0.0),
        end_effector_mass_kg=0.5,
    )
    physics = Ft300Physics(offset_n=(0.1, 0.2, 0.3), lever_arm_m=(0.0, 0.0, 0.1))
    force, torque = wrench_from_truth(truth, physics)
    g = STANDARD_GRAVITY_M_PER_S2
    # R_wt^T maps world z to tool +y and world y to tool -z.
    load = 0.5 * np.array([2.0, g, 0.0])
    np.testing.assert_allclose(force, np.array([0.0, 5.0, 0.0]) + load + [0.1, 0.2, 0.3],
                               atol=1e-12)
    np.testing.assert_allclose(torque, np.array([0.0, 0.0, -1.0]) + np.cross([0, 0, 0.1], load),
                               atol=1e-12)


def test_frames_carry_quantised_noisy_saturated_physics():
    truth = Truth(force_n=(0.0, 0.0, 1000.0), end_effector_mass_kg=1.0)
    model = Ft300Model(
        rng=np.random.default_rng(3),
        truth=lambda t: truth,
        physics=Ft300Physics(noise_std_n=0.2, noise_std_nm=0.0),
    )
    model.receive(write_request(410, [0x0200]), 0.0)
    parser = FixedFrameParser(STREAM_HEADER, STREAM_FRAME_LENGTH)
    frames = parser.feed(model.emit(0.005)[8:])
    for k in range(1, 201):
        frames += parser.feed(model.emit(k * 0.01))
    counts = np.array([decode_stream_frame(f) for f in frames], dtype=float)
    assert len(counts) >= 190
    np.testing.assert_array_equal(counts[:, 2], 30000)  # 1009.8 N saturates at 300 N
    assert abs(counts[:, 0].std() / 100 - 0.2) < 0.03  # the noise
    assert np.all(counts[:, 3:] == 0)
