"""The robotiq-ft300 sensor in emulated mode: a real pseudo-terminal, the kit, the physics."""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
import pytest

from hapticframe.devices import FakeClock, LifecycleState, SerialTransport
from hapticframe.kinds import BuildContext, concatenate_batches
from hapticframe.testing import make_component, run_checks
from hapticframe_robotiq import Ft300Config
from hapticframe_robotiq._emulator import STANDARD_GRAVITY_M_PER_S2
from hapticframe_robotiq._sensor import Ft300Sensor
from hapticframe_robotiq.plugin import SPECS

SPEC = SPECS[0]


def _context(**kwargs) -> BuildContext:
    return BuildContext(id="wrist", rng=np.random.default_rng(3), **kwargs)


def test_the_kit_passes():
    results = run_checks(SPEC)
    failed = [(r.check, r.message) for r in results if r.status != "PASS"]
    assert not failed, failed
    assert {r.check for r in results} >= {
        "check_sensor_contract", "check_sensor_valid_samples_finite", "check_deterministic",
    }


def test_emulated_port_is_a_real_pty_opened_by_pyserial():
    serial = pytest.importorskip("serial")
    sensor = Ft300Sensor(Ft300Config(port="emulated"), _context())
    try:
        sensor.configure()
        transport = sensor._transport
        assert isinstance(transport, SerialTransport)
        assert isinstance(transport.port, serial.Serial)
        path = sensor.emulator.path
        assert os.path.islink(path) and os.readlink(path).startswith("/dev/pts/")
        assert transport.url == path
        assert sensor.device_info.firmware == "FTS-3.0.1"
        assert sensor.device_info.serial_number == "ROB-1234"
        assert not sensor.live
        assert sensor.lifecycle_state is LifecycleState.INACTIVE
        sensor.activate()
        batch = concatenate_batches([sensor.read() for _ in range(50)])
        assert 45 <= len(batch) <= 55
        assert batch.valid["force_n"].all()
        # Tared at rest: zero mean within the emulator's noise (0.1 N).
        assert np.abs(batch.channels["force_n"].mean(axis=0)).max() < 0.1
    finally:
        sensor.close()
    assert sensor.lifecycle_state is LifecycleState.FINALIZED
    assert not os.path.exists(path)
    # The deactivation jammed the stream: the device went back to Modbus.
    assert sensor.model is not None and not sensor.model.streaming


def test_faults_through_the_pty_disconnect_and_standard():
    config = Ft300Config(
        port="emulated",
        faults=({"kind": "disconnect", "at_s": 0.5, "duration_s": 0.15},
                {"kind": "bad_crc", "rate_hz": 4.0}),
    )
    sensor = Ft300Sensor(config, _context())
    try:
        sensor.configure()
        sensor.activate()
        # 2 s of reads: the recovery takes device time read by read (it never blocks one).
        batch = concatenate_batches([b for b in (sensor.read() for _ in range(200)) if len(b)])
        health = sensor.health
        assert health.reconnects == 1 and health.crc_errors >= 1, health.as_dict()
        assert sensor.emulator.stats["disconnects"] == 1
        assert len(batch) > 100
        assert batch.timestamps_s[-1] >= 1.4  # it went on after the replug
    finally:
        sensor.close()
    standard = Ft300Sensor(Ft300Config(port="emulated", faults="standard"), _context())
    try:
        standard.configure()
        standard.activate()
        for _ in range(200):
            standard.read()
        assert standard.lifecycle_state is LifecycleState.ACTIVE
    finally:
        standard.close()


@dataclass(frozen=True)
class Truth:
    timestamp_s: float
    orientation_wxyz: tuple[float, ...] = (1.0, 0.0, 0.0, 0.0)
    linear_acceleration_m_per_s2: tuple[float, ...] = (0.0, 0.0, 0.0)
    force_n: tuple[float, ...] = (0.0, 0.0, 0.0)
    torque_nm: tuple[float, ...] = (0.0, 0.0, 0.0)
    end_effector_mass_kg: float = 0.8


@dataclass
class FakeRobot:
    """A physical-truth source: at rest until 1 s, then pushed and accelerated."""

    truth_time_s: float = 0.0
    asked: list[float] = field(default_factory=list)

    def physical_truth(self, timestamp_s: float) -> Truth:
        self.asked.append(timestamp_s)
        assert timestamp_s <= self.truth_time_s + 1e-9  # never asked about the future
        if timestamp_s < 1.0:
            return Truth(timestamp_s)
        return Truth(timestamp_s, linear_acceleration_m_per_s2=(0.0, 0.0, 2.0),
                     force_n=(3.0, 0.0, 0.0), torque_nm=(0.0, 0.0, 0.5))


def test_emulated_sensor_measures_the_robot_truth_in_simulation_time():
    robot = FakeRobot()
    config = Ft300Config(port="emulated", noise_std_n=0.0, noise_std_nm=0.0, frozen_frames=None)
    sensor = Ft300Sensor(config, _context(inputs={"robot": robot}))
    assert isinstance(sensor.clock, FakeClock)
    try:
        sensor.configure()
        sensor.activate()
        batches = []
        for step in range(1, 201):
            robot.truth_time_s = step * 0.01  # the simulation advances 10 ms per step
            batches.append(sensor.read())
        batch = concatenate_batches([b for b in batches if len(b)])
    finally:
        sensor.close()
    t = batch.timestamps_s
    assert t[0] >= 0.0 and t[-1] <= 2.0 + 1e-9  # the simulation's time base
    assert len(batch) >= 190
    force = batch.channels["force_n"]
    torque = batch.channels["torque_nm"]
    # The tare at rest removed m_e g; from 1 s the push and m_e a show (sensor frame = tool).
    rest = force[t < 0.99]
    np.testing.assert_allclose(rest, 0.0, atol=0.006)
    moving = force[t > 1.02]
    np.testing.assert_allclose(moving, np.tile([3.0, 0.0, 0.8 * 2.0], (len(moving), 1)),
                               atol=0.006)
    np.testing.assert_allclose(torque[t > 1.02][:, 2], 0.5, atol=0.0006)
    offset, _ = sensor.offsets
    assert offset[2] == pytest.approx(0.8 * STANDARD_GRAVITY_M_PER_S2, abs=0.006)


def test_a_robot_without_physical_truth_is_refused():
    class Blind:
        pass

    with pytest.raises(ValueError, match="PhysicalTruthSource"):
        Ft300Sensor(Ft300Config(port="emulated"), _context(inputs={"robot": Blind()}))


def test_config_rules():
    with pytest.raises(ValueError, match="need port 'emulated'"):
        Ft300Config(port="/dev/ttyUSB0", faults="standard")
    with pytest.raises(ValueError, match="frame_timeout_s"):
        Ft300Config(port="emulated", byte_timeout_s=0.2, frame_timeout_s=0.1)
    with pytest.raises(ValueError, match="kind"):
        Ft300Config(port="emulated", faults=[{"at_s": 1.0}])
    assert Ft300Config(port="emulated", faults=[{"kind": "bad_crc", "at_s": 1.0}]).faults == (
        {"kind": "bad_crc", "at_s": 1.0},
    )


def test_a_real_port_that_cannot_open_fails_configure_with_a_device_error():
    pytest.importorskip("serial")
    from hapticframe.devices import DeviceError
    from hapticframe.testing import CheckFailure

    # The kit configures and activates a device it builds, as a run does: the port that
    # cannot open fails configure with a DeviceError naming it.
    with pytest.raises(CheckFailure, match="/nonexistent/ttyUSB9") as failure:
        make_component(SPEC, config={"port": "/nonexistent/ttyUSB9"})
    assert isinstance(failure.value.__cause__, DeviceError)


@pytest.mark.parametrize(
    ("fault", "lost"),
    [
        # A slow link: frames arrive up to a period late, in bursts; none is lost.
        ({"kind": "fragment", "at_s": 0.5, "duration_s": 20.0}, False),
        ({"kind": "stall", "rate_hz": 1.0, "duration_s": 0.05}, False),
        # Frames lost: the parser discards them, or the link drops what a stall held.
        ({"kind": "bad_crc", "rate_hz": 1.0}, True),
        ({"kind": "stall", "rate_hz": 1.0, "duration_s": 0.1, "params": {"drop": 1}}, True),
    ],
)
def test_sample_times_keep_the_stream_period_whatever_the_reads_jitter(fault, lost):
    # A force rate is a difference over these times: a frame dated 2 ms after the previous
    # one (it was read late, the next on time) would make a 5x rate spike out of noise.
    sensor = make_component(
        SPEC, config={"port": "emulated", "tare_s": 0.0, "noise_std_n": 0.3, "faults": [fault]}
    )
    try:
        batch = concatenate_batches([sensor.read() for _ in range(2000)])
        health = sensor.health.as_dict()
    finally:
        sensor.close()
    periods = np.diff(batch.timestamps_s) / 0.01
    np.testing.assert_allclose(periods, np.round(periods), atol=1e-6)
    assert periods.min() > 0.999
    missing = int(np.round(periods).sum() - len(periods))
    assert (missing > 0) == lost
    # Without a sequence counter a lost frame is inferred; the driver errs low (a frame
    # counted lost that was not would date the next one onto its predecessor).
    assert 0.9 * missing <= health["dropped_samples"] <= missing


def test_reading_before_activate_is_refused():
    from hapticframe.devices import DeviceError

    sensor = Ft300Sensor(Ft300Config(port="emulated"), _context())
    try:
        with pytest.raises(DeviceError, match="activate"):
            sensor.read()
        sensor.configure()
        with pytest.raises(DeviceError, match="inactive"):
            sensor.read()
        sensor.activate()
        sensor.read()
    finally:
        sensor.close()
