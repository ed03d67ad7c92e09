"""BNO055 driver against its emulator on a pty: readings, fault matrix, bounded recovery, kit."""

import math

import numpy as np
import pytest

import hapticframe.kinds as kinds
from hapticframe.devices import DeviceError, LifecycleState
from hapticframe.geometry import rotation_matrix_from_rpy_deg, wxyz_from_rotation_matrix
from hapticframe.kinds import BuildContext, concatenate_batches
from hapticframe.testing import run_checks
from hapticframe_bno055._config import Bno055SensorConfig
from hapticframe_bno055._sensor import CHANNELS, Bno055Sensor
from hapticframe_bno055.plugin import SPECS

#: At rest and level, quantised to the registers: 9.80665 m/s² → 981 LSB.
AT_REST = {
    "acceleration_m_per_s2": [0.0, 0.0, 9.81],
    "linear_acceleration_m_per_s2": [0.0, 0.0, 0.0],
    "gravity_m_per_s2": [0.0, 0.0, 9.81],
    "angular_velocity_rad_per_s": [0.0, 0.0, 0.0],
    "orientation_wxyz": [1.0, 0.0, 0.0, 0.0],
    "calibration": [3.0, 3.0, 3.0, 3.0],
}


def make(inputs=None, *, activate=True, **config):
    """A sensor, configured and activated as a run does (``activate=False``: as built)."""
    config = {"accel_noise_std_m_per_s2": 0.0, **config}
    sensor = Bno055Sensor(
        Bno055SensorConfig(**config),
        BuildContext(id="imu", rng=np.random.default_rng(0), inputs=inputs or {}),
    )
    if activate:
        sensor.configure()
        sensor.activate()
    return sensor


def read_all(sensor, reads):
    batches = [sensor.read() for _ in range(reads)]
    return concatenate_batches([b for b in batches if len(b)])


def assert_valid_samples_are_true(batch, expected=AT_REST):
    """Every sample a channel marks valid equals the emulator's truth (exactly, at rest)."""
    for name, values in expected.items():
        valid = batch.valid[name]
        assert np.all(np.isfinite(batch.channels[name][valid]))
        np.testing.assert_array_equal(
            batch.channels[name][valid], np.broadcast_to(values, batch.channels[name][valid].shape),
            err_msg=name,
        )
        assert np.all(np.isnan(batch.channels[name][~valid]))


def test_at_rest_reads_gravity_along_z():
    sensor = make()
    try:
        batch = read_all(sensor, 50)
        assert len(batch) == 50  # one sample per poll, one poll per read without a robot
        assert all(batch.valid[name].all() for name in CHANNELS)
        assert_valid_samples_are_true(batch)
        assert np.all(np.diff(batch.timestamps_s) > 0)
        np.testing.assert_allclose(np.diff(batch.timestamps_s), 0.01, atol=1e-9)
        assert sensor.health.faults() == {}
        assert sensor.health.frames >= 50
    finally:
        sensor.close()
    assert sensor.lifecycle_state is LifecycleState.FINALIZED


def test_accelerometer_noise_is_seeded():
    first, second = make(accel_noise_std_m_per_s2=0.05), make(accel_noise_std_m_per_s2=0.05)
    try:
        a, b = read_all(first, 20), read_all(second, 20)
        np.testing.assert_array_equal(a.channels["acceleration_m_per_s2"],
                                      b.channels["acceleration_m_per_s2"])
        z = a.channels["acceleration_m_per_s2"][:, 2]
        assert z.std() > 0.01 and abs(z.mean() - 9.807) < 0.05
    finally:
        first.close()
        second.close()


def test_rotated_mount_shows_up():
    sensor = make(mount_rpy_deg=(30.0, 0.0, 0.0))
    try:
        batch = read_all(sensor, 10)
    finally:
        sensor.close()
    g = 9.80665
    expected = [0.0, g * math.sin(math.radians(30)), g * math.cos(math.radians(30))]
    np.testing.assert_allclose(batch.channels["acceleration_m_per_s2"], np.tile(expected, (10, 1)),
                               atol=0.005)
    np.testing.assert_allclose(batch.channels["gravity_m_per_s2"], np.tile(expected, (10, 1)),
                               atol=0.005)
    quaternion = [math.cos(math.radians(15)), math.sin(math.radians(15)), 0.0, 0.0]
    np.testing.assert_allclose(batch.channels["orientation_wxyz"], np.tile(quaternion, (10, 1)),
                               atol=1e-4)
    assert batch.valid["orientation_wxyz"].all()


def test_accgyro_mode_marks_fused_channels_invalid():
    sensor = make(mode="accgyro")
    try:
        batch = read_all(sensor, 10)
    finally:
        sensor.close()
    assert batch.valid["acceleration_m_per_s2"].all()
    for name in ("orientation_wxyz", "gravity_m_per_s2", "linear_acceleration_m_per_s2"):
        assert not batch.valid[name].any() and np.isnan(batch.channels[name]).all()
    np.testing.assert_array_equal(batch.channels["calibration"][0], [0, 3, 3, 0])
    assert sensor.health.invalid_samples == 0  # no fusion is a mode, not a fault


# kind, params, duration_s, counters of which at least one must be non-zero
FAULT_MATRIX = [
    ("bus_overrun", {"count": 2}, 0.0, ("bus_overruns",)),
    ("status", {"code": 2}, 0.0, ("status_errors",)),
    ("status", {"code": 10}, 0.0, ("char_timeouts",)),
    ("no_reply", {"count": 2}, 0.0, ("timeouts",)),
    ("partial_reply", {}, 0.0, ("timeouts",)),
    ("wrong_length", {}, 0.0, ("framing_errors",)),
    ("stale_bytes", {"count": 5}, 0.0, ("framing_errors",)),
    ("rx_stall", {}, 0.0, ("char_timeouts",)),
    ("reset", {}, 0.0, ("recoveries",)),
    ("bad_quaternion", {}, 0.05, ("invalid_samples",)),
    ("bad_gravity", {}, 0.05, ("invalid_samples",)),
    ("garbage", {"count": 3}, 0.0, ("framing_errors", "resyncs")),
    ("drop_bytes", {"count": 2}, 0.0, ("timeouts",)),
    ("stall", {}, 0.08, ("timeouts",)),
    ("disconnect", {}, 0.2, ("reconnects",)),
    ("fragment", {}, 0.2, ()),
    ("calib_drop", {}, 0.2, ()),
]


@pytest.mark.parametrize(
    ("kind", "params", "duration_s", "counters"), FAULT_MATRIX,
    ids=[f"{row[0]}-{i}" for i, row in enumerate(FAULT_MATRIX)],
)
def test_fault_matrix(kind, params, duration_s, counters):
    sensor = make(faults=[{"kind": kind, "at_s": 0.3, "duration_s": duration_s, "params": params}])
    try:
        batch = read_all(sensor, 150)
        injected = sensor.faults.count(kind)
    finally:
        sensor.close()
    assert injected >= 1, f"{kind} never fired"
    health = sensor.health.as_dict()
    if counters:
        assert any(health[c] > 0 for c in counters), health
    # No corrupted sample is valid: each valid value is the emulator's truth, exactly.
    expected = dict(AT_REST)
    if kind == "calib_drop":
        calibration = batch.channels["calibration"]
        assert (calibration == 0).all(axis=1).any() and (calibration == 3).all(axis=1).any()
        del expected["calibration"]
    assert_valid_samples_are_true(batch, expected)
    if kind in ("bad_quaternion", "bad_gravity"):
        assert not batch.valid["orientation_wxyz"].all()
    # Survived: still delivering valid samples at the end.
    assert batch.valid["orientation_wxyz"][-5:].all()
    assert batch.timestamps_s[-1] > 1.4
    assert len(batch) >= 60


def test_min_system_calibration_invalidates_fusion_while_calibration_drops():
    sensor = make(min_system_calibration=3,
                  faults=[{"kind": "calib_drop", "at_s": 0.2, "duration_s": 0.1}])
    try:
        batch = read_all(sensor, 50)
    finally:
        sensor.close()
    dropped = batch.channels["calibration"][:, 0] == 0
    assert dropped.sum() >= 8
    np.testing.assert_array_equal(batch.valid["orientation_wxyz"], ~dropped)
    assert batch.valid["acceleration_m_per_s2"].all()
    assert sensor.health.invalid_samples == dropped.sum()


@pytest.mark.parametrize(("count", "overruns", "dropped"), [(3, 3, 0), (4, 4, 1), (9, 9, 2)])
def test_overrun_retries_are_bounded(count, overruns, dropped):
    sensor = make(max_retries=3,
                  faults=[{"kind": "bus_overrun", "at_s": 0.2, "params": {"count": count}}])
    try:
        read_all(sensor, 40)
        model = sensor.model
    finally:
        sensor.close()
    # Each poll sends one request and at most max_retries resends.
    assert sensor.health.bus_overruns == overruns
    assert sensor.health.dropped_samples == dropped
    assert sensor.health.recoveries == 0
    assert model.requests <= 40 * 4 + 10


def test_a_device_that_never_answers_raises_after_bounded_recovery():
    sensor = make(faults=[{"kind": "no_reply", "at_s": 0.2, "params": {"count": 10**9}}])
    def read_until_it_fails():
        for _ in range(1000):
            sensor.read()

    with pytest.raises(DeviceError, match="did not recover after 3 attempts") as caught:
        read_until_it_fails()
    assert "imu" in str(caught.value)
    assert sensor.lifecycle_state is LifecycleState.ERROR
    assert sensor.health.recoveries == 3
    assert sensor.clock.now() < 30.0  # bounded in device time too
    sensor.close()


def test_configure_fails_clearly_on_a_silent_device():
    sensor = make(
        faults=[{"kind": "no_reply", "at_s": 0.0, "params": {"count": 10**9}}], activate=False
    )
    with pytest.raises(DeviceError, match="CHIP_ID"):
        sensor.configure()
    sensor.close()


def test_a_port_that_does_not_exist_fails_configure():
    sensor = make(port="/nonexistent/ttyBNO055", activate=False)
    assert sensor.live
    with pytest.raises(DeviceError, match="configure failed"):
        sensor.configure()
    sensor.close()


def test_faults_need_the_emulator():
    with pytest.raises(ValueError, match="emulated"):
        Bno055SensorConfig(port="/dev/ttyUSB0", faults="standard")


def test_standard_schedule_is_survived_and_counted():
    sensor = make(faults="standard")
    try:
        batch = read_all(sensor, 2000)  # 20 s of device time
        faults = sensor.health.faults()
    finally:
        sensor.close()
    assert len(batch) > 1700
    assert {"bus_overruns", "framing_errors", "timeouts"} <= set(faults)
    expected = {k: v for k, v in AT_REST.items() if k != "calibration"}
    assert_valid_samples_are_true(batch, expected)


class _TruthSource:
    """A robot stand-in: the tool rolled 20°, accelerating along world x, turning about z."""

    def __init__(self):
        self.truth_time_s = 12.0  # the simulation need not start at 0
        self.rotation = rotation_matrix_from_rpy_deg([20.0, 0.0, 0.0])

    def physical_truth(self, timestamp_s):
        zero = np.zeros(3)
        return kinds.PhysicalTruth(
            timestamp_s=min(timestamp_s, self.truth_time_s), position_m=zero,
            orientation_wxyz=wxyz_from_rotation_matrix(self.rotation),
            linear_velocity_m_per_s=zero,
            linear_acceleration_m_per_s2=np.array([1.5, 0.0, 0.0]),
            angular_velocity_rad_per_s=np.array([0.0, 0.0, 0.4]), force_n=zero, torque_nm=zero,
            end_effector_mass_kg=0.8,
        )


def test_robot_input_drives_the_emulated_imu():
    robot = _TruthSource()
    sensor = make(inputs={"robot": robot})
    try:
        batches = []
        for _ in range(30):
            robot.truth_time_s += 0.01
            batches.append(sensor.read())
            assert sensor.clock.now() >= robot.truth_time_s
        batch = concatenate_batches([b for b in batches if len(b)])
    finally:
        sensor.close()
    assert len(batch) >= 25 and sensor.health.dropped_samples == 0
    assert 12.0 < batch.timestamps_s[0] < 12.1
    r = robot.rotation
    g = np.array([0.0, 0.0, 9.80665])
    np.testing.assert_allclose(batch.channels["acceleration_m_per_s2"][-1],
                               r.T @ ([1.5, 0, 0] + g), atol=0.006)
    np.testing.assert_allclose(batch.channels["linear_acceleration_m_per_s2"][-1],
                               r.T @ [1.5, 0, 0], atol=0.006)
    np.testing.assert_allclose(batch.channels["angular_velocity_rad_per_s"][-1],
                               r.T @ [0, 0, 0.4], atol=0.002)
    assert batch.valid["orientation_wxyz"].all()


def test_an_input_without_physical_truth_is_refused():
    with pytest.raises(ValueError, match="PhysicalTruthSource"):
        make(inputs={"robot": object()})


def test_kit_conformance():
    results = run_checks(SPECS[0])
    failed = [r for r in results if r.status != "PASS"]
    assert not failed, failed
    assert {r.check for r in results} >= {"check_sensor_contract", "check_deterministic"}


def test_reading_before_activate_is_refused():
    sensor = make(activate=False)
    with pytest.raises(DeviceError, match="activate"):
        sensor.read()
    sensor.configure()
    with pytest.raises(DeviceError, match="inactive"):
        sensor.read()
    sensor.activate()
    assert len(read_all(sensor, 5))
    sensor.close()


def test_a_read_on_a_live_port_never_waits_out_the_reconnect_backoff():
    """Issue 26 §6: a live host (its clock moved by the test between reads) whose IMU is
    unplugged at 1 s and back at 2 s. A read may wait for one request's reply, never for
    the recovery's backoff: that runs in steps, one per poll slot, across reads."""
    from hapticframe.devices import EmulatedTransport, FakeClock, FaultSchedule, LinkPort
    from hapticframe_bno055._emulator import Bno055Model

    clock = FakeClock(0.0)
    schedule = FaultSchedule.from_config(
        [{"kind": "disconnect", "at_s": 1.0, "duration_s": 1.0}], np.random.default_rng(1))
    model = Bno055Model(faults=schedule, rng=np.random.default_rng(2))
    port = LinkPort(EmulatedTransport(model, clock, schedule), clock, "usb-imu")
    config = Bno055SensorConfig(port="usb-imu", accel_noise_std_m_per_s2=0.0)
    sensor = Bno055Sensor(config, BuildContext(id="imu", rng=np.random.default_rng(0)),
                          port=port)
    sensor.configure()
    sensor.activate()
    one_request_s = (config.max_retries + 1) * (config.reply_timeout_s + 2 * config.poll_step_s)
    longest, after = 0.0, 0
    try:
        while clock.now() < 4.0:
            clock.advance(0.01)
            before = clock.now()
            batch = sensor.read()
            longest = max(longest, clock.now() - before)
            after += len(batch) if before > 2.5 else 0
        assert longest <= one_request_s, longest
        assert sensor.health.reconnects >= 1 and sensor.health.recoveries >= 1
        assert after > 50  # streaming again after the replug
    finally:
        sensor.close()
