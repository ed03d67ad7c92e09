"""Physical truth of simulated robots: the record, the protocol, and the sandbox robot's truth
(inertia, speed profile, sample-and-hold, rewind); the default config keeps old results."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest

from hapticframe import Circle, Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement, PhysicalTruth, PhysicalTruthSource
from hapticframe.testing import run_checks
from hapticframe_sandbox import (
    SandboxForceSensor,
    SandboxForceSensorConfig,
    SandboxRobot,
    SandboxRobotConfig,
)
from hapticframe_sandbox import _functional as F
from hapticframe_sandbox import plugin as sandbox_plugin

STANDARD_GRAVITY = 9.80665
DT = 0.01  # the default control period


def scene() -> Scene:
    return Scene(objects=[Circle(center_m=(0.3, 0.25), radius_m=0.04)])


def robot_and_sensor(seed: int = 11, **config):
    robot = SandboxRobot(
        SandboxRobotConfig(**config),
        BuildContext(id="arm", rng=np.random.default_rng(seed), scene=scene()),
    )
    sensor = SandboxForceSensor(
        SandboxForceSensorConfig(),
        BuildContext(id="ft", rng=np.random.default_rng(seed + 1), inputs={"arm": robot}),
    )
    return robot, sensor


def steps(robot: SandboxRobot, movement: ExploratoryMovement):
    robot.begin(movement)
    states = []
    while (state := robot.step()) is not None:
        states.append(state)
    return states


def truth_arrays(robot: SandboxRobot, times):
    records = [robot.physical_truth(t) for t in times]
    return {
        field.name: np.array([getattr(r, field.name) for r in records])
        for field in dataclasses.fields(PhysicalTruth)
    }


def same(a: PhysicalTruth, b: PhysicalTruth) -> bool:
    """Field-by-field equality (the record's arrays make ``==`` ambiguous)."""
    return all(
        np.array_equal(getattr(a, f.name), getattr(b, f.name))
        for f in dataclasses.fields(PhysicalTruth)
    )


def valid_truth(**overrides) -> PhysicalTruth:
    fields = {
        "timestamp_s": 0.5,
        "position_m": [0.1, 0.2, -0.03],
        "orientation_wxyz": [1.0, 0.0, 0.0, 0.0],
        "linear_velocity_m_per_s": np.zeros(3),
        "linear_acceleration_m_per_s2": np.zeros(3),
        "angular_velocity_rad_per_s": np.zeros(3),
        "force_n": [-12.0, 3.0, 0.0],
        "torque_nm": [0.3, 1.2, 0.0],
        "end_effector_mass_kg": 0.8,
    }
    fields.update(overrides)
    return PhysicalTruth(**fields)


# --- the record and the protocol --------------------------------------------------------------


def test_the_record_owns_read_only_float_arrays():
    force = np.array([-12.0, 3.0, 0.0])
    truth = valid_truth(force_n=force)
    force[0] = 99.0
    assert truth.force_n[0] == -12.0  # copied, not shared
    for field in dataclasses.fields(PhysicalTruth):
        value = getattr(truth, field.name)
        if isinstance(value, np.ndarray):
            assert value.dtype == np.float64 and not value.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        truth.position_m[0] = 1.0
    assert isinstance(truth.timestamp_s, float) and isinstance(truth.end_effector_mass_kg, float)


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"position_m": [0.0, 0.0]}, "position_m must have shape"),
        ({"orientation_wxyz": [1.0, 0.0, 0.0]}, "orientation_wxyz must have shape"),
        ({"torque_nm": np.zeros((1, 3))}, "torque_nm must have shape"),
        ({"force_n": [np.nan, 0.0, 0.0]}, "force_n contains NaN"),
        ({"linear_acceleration_m_per_s2": [0.0, np.inf, 0.0]}, "NaN or infinity"),
        ({"orientation_wxyz": [1.0, 0.1, 0.0, 0.0]}, "unit quaternion"),
        ({"end_effector_mass_kg": -0.1}, "non-negative"),
        ({"end_effector_mass_kg": math.nan}, "non-negative"),
        ({"timestamp_s": math.inf}, "timestamp_s must be finite"),
    ],
)
def test_the_record_rejects_malformed_values(overrides, message):
    with pytest.raises(ValueError, match=message):
        valid_truth(**overrides)


def test_rotation_matrix_of_the_record():
    half = math.radians(30.0) / 2
    truth = valid_truth(orientation_wxyz=[math.cos(half), 0.0, 0.0, math.sin(half)])
    c, s = math.cos(math.radians(30.0)), math.sin(math.radians(30.0))
    expected = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(truth.rotation_matrix, expected, atol=1e-15)


def test_the_sandbox_robot_is_a_truth_source_and_other_components_are_not():
    robot, sensor = robot_and_sensor()
    assert isinstance(robot, PhysicalTruthSource)
    assert not isinstance(sensor, PhysicalTruthSource)


def test_config_bounds():
    for bad in ({"end_effector_mass_kg": 0.0}, {"acceleration_m_per_s2": 0.0},
                {"acceleration_m_per_s2": -1.0}, {"sensor_height_m": -0.01}):
        with pytest.raises(ValueError, match=next(iter(bad))):
            SandboxRobotConfig(**bad)
    cfg = SandboxRobotConfig()
    assert (cfg.end_effector_mass_kg, cfg.acceleration_m_per_s2, cfg.sensor_height_m) == (
        0.8, None, 0.1
    )


# --- the default config changes nothing -------------------------------------------------------

SEQUENCE = (
    ExploratoryMovement((0.05, 0.45), (0.2, 0.40)),
    ExploratoryMovement((0.1, 0.25), (0.34, 0.25)),  # into the circle: force limit
    ExploratoryMovement((0.1, 0.1), (0.5, 0.3), speed_m_per_s=0.08),  # halted after 60 steps
)


def run_sequence(robot: SandboxRobot, sensor: SandboxForceSensor):
    reads = []
    per_movement = []
    for k, movement in enumerate(SEQUENCE):
        robot.begin(movement)
        n, total = 0, 0.0
        while robot.step() is not None:
            n += 1
            total += float(np.sum(sensor.read().channels["force_n"]))
            if k == 2 and n == 60:
                robot.halt("test")
        per_movement.append((n, robot.halt_reason, robot.state.position_m.tolist(), total))
        reads.append(total)
    return per_movement


@pytest.mark.parametrize("extra", [{}, {"end_effector_mass_kg": 3.0, "sensor_height_m": 0.3}])
def test_default_profile_reproduces_the_results_from_before_physical_truth(extra):
    # Numbers recorded from the sandbox before physical truth existed (same seeds, same
    # sequence); mass and sensor height must not change them either.
    robot, sensor = robot_and_sensor(**extra)
    per_movement = run_sequence(robot, sensor)
    expected = [
        (317, "", [0.2, 0.4], -2344.476970286286),
        (334, "force_limit", [0.2670000000000001, 0.25], -7008.059172768399),
        (60, "test", [0.142932505167996, 0.12146625258399799], -328.75889164427156),
    ]
    for (n, reason, position, total), (n0, reason0, position0, total0) in zip(
        per_movement, expected, strict=True
    ):
        assert (n, reason) == (n0, reason0)
        np.testing.assert_allclose(position, position0, rtol=1e-12)
        assert total == pytest.approx(total0, rel=1e-9)
    g = robot.ground_truth
    assert len(g) == 711
    assert float(g.forces_n.sum()) == pytest.approx(-9689.782202424884, rel=1e-9)
    assert float((g.forces_n**2).sum()) == pytest.approx(369163.95205061324, rel=1e-9)
    np.testing.assert_allclose(
        g.forces_n[[0, 100, 250, 710]],
        [[-0.09973830557195935, 0.03324610185731977], [-11.071463007203613, 3.6904876690678696],
         [-14.96072960277716, 4.986909867592384], [-6.64134264245512, -3.320671321227559]],
        rtol=1e-9,
    )
    # The old position formula, step by step: advance min(v dt, what is left) along the line.
    offset = 0
    for movement, (n, *_rest) in zip(SEQUENCE, per_movement, strict=True):
        travelled, expected_positions = 0.0, []
        direction = (movement.end_m - movement.start_m) / movement.length_m
        for _ in range(n):
            travelled += min(movement.speed_m_per_s * DT, movement.length_m - travelled)
            expected_positions.append(movement.start_m + travelled * direction)
        np.testing.assert_allclose(
            g.positions_m[offset : offset + n], expected_positions, rtol=0, atol=1e-15
        )
        offset += n


def test_default_profile_truth_has_constant_velocity_and_no_acceleration():
    robot, _ = robot_and_sensor()
    movement = ExploratoryMovement((0.05, 0.45), (0.15, 0.45), speed_m_per_s=0.05)
    states = steps(robot, movement)
    truth = truth_arrays(robot, [s.timestamp_s for s in states])
    np.testing.assert_array_equal(truth["linear_velocity_m_per_s"][:, 0], 0.05)
    np.testing.assert_array_equal(truth["linear_acceleration_m_per_s2"], 0.0)
    np.testing.assert_array_equal([s.speed_m_per_s for s in states], 0.05)


# --- the trapezoidal speed profile ------------------------------------------------------------


@pytest.mark.parametrize(
    ("length", "speed", "accel"),
    [
        (0.1, 0.05, 0.5),  # ramps of 0.1 s: phase changes on step boundaries
        (0.1, 0.05, 0.3),  # ramps of 1/6 s: phase changes inside a step
        (0.002, 0.05, 0.5),  # too short to reach the speed: a triangle
    ],
)
def test_trapezoid_profile_timing_and_integration(length, speed, accel):
    robot, _ = robot_and_sensor(acceleration_m_per_s2=accel)
    start = np.array([0.05, 0.45])
    heading = math.radians(-30.0)
    direction = np.array([math.cos(heading), math.sin(heading)])
    movement = ExploratoryMovement(start, start + length * direction, speed_m_per_s=speed)
    states = steps(robot, movement)
    peak = min(speed, math.sqrt(accel * length))
    total = length / peak + peak / accel  # cruise + one ramp's worth of extra time
    assert len(states) == math.ceil(total / DT - 1e-9)
    times = np.array([s.timestamp_s for s in states])
    truth = truth_arrays(robot, times)
    position = truth["position_m"][:, :2]
    velocity = truth["linear_velocity_m_per_s"][:, :2]
    acceleration = truth["linear_acceleration_m_per_s2"][:, :2]
    along = acceleration @ direction
    np.testing.assert_allclose(acceleration, np.outer(along, direction), atol=1e-12)
    # Ends at the end point, at rest; never faster than the speed; accelerations bounded.
    np.testing.assert_allclose(position[-1], movement.end_m, atol=1e-15)
    np.testing.assert_array_equal(velocity[-1], 0.0)
    speeds = velocity @ direction
    # The peak falls between two steps in a triangle.
    assert peak - accel * DT <= speeds.max() <= peak * (1 + 1e-12) and speeds.min() >= 0
    assert np.abs(along).max() <= accel * (1 + 1e-9)
    assert along[0] == pytest.approx(accel) and along[-1] < 0
    if length / speed > 1.0:  # a cruise phase: zero acceleration there
        assert (along == 0.0).sum() >= 150
    # Acceleration integrates to velocity, velocity to position (from rest at the start).
    np.testing.assert_allclose(np.cumsum(acceleration, axis=0) * DT, velocity, atol=1e-12)
    previous = np.vstack([start, position[:-1]])
    previous_velocity = np.vstack([np.zeros(2), velocity[:-1]])
    np.testing.assert_allclose(
        position - previous, 0.5 * (velocity + previous_velocity) * DT, atol=accel * DT**2
    )
    # The exact profile at the step times, and the robot's states agree with the truth.
    timing = F.trapezoid_timing(length, speed, accel)
    exact = [F.trapezoid_motion((k + 1) * DT, length, accel, timing)[0] for k in range(len(states))]
    np.testing.assert_allclose((position - start) @ direction, exact, atol=1e-15)
    np.testing.assert_allclose([s.position_m for s in states], position, atol=0)
    np.testing.assert_allclose([s.speed_m_per_s for s in states], speeds, atol=1e-15)


def test_trapezoid_timing_function():
    t = F.trapezoid_timing(0.1, 0.05, 0.5)
    assert t == pytest.approx((0.05, 0.1, 2.0, 2.1))
    t = F.trapezoid_timing(0.002, 0.05, 0.5)
    assert t.peak_speed_m_per_s == pytest.approx(math.sqrt(0.001))
    assert t.cruise_end_s == t.ramp_end_s and t.total_s == pytest.approx(2 * t.ramp_end_s)
    assert F.trapezoid_motion(-1.0, 0.1, 0.5, F.trapezoid_timing(0.1, 0.05, 0.5)) == (0.0, 0.0)
    assert F.trapezoid_motion(5.0, 0.1, 0.5, F.trapezoid_timing(0.1, 0.05, 0.5)) == (0.1, 0.0)
    with pytest.raises(ValueError, match="acceleration"):
        F.trapezoid_timing(0.1, 0.05, 0.0)


def test_a_halt_stops_at_once_and_the_next_movement_starts_from_rest():
    robot, _ = robot_and_sensor(acceleration_m_per_s2=0.5)
    robot.begin(ExploratoryMovement((0.05, 0.45), (0.25, 0.45)))
    for _ in range(50):
        robot.step()
    robot.halt("test")
    assert robot.step() is None
    held = robot.physical_truth(robot.truth_time_s)
    assert held.linear_velocity_m_per_s[0] == pytest.approx(0.05)  # the last step, held
    robot.begin(ExploratoryMovement((0.05, 0.40), (0.25, 0.40)))
    first = robot.step()
    truth = robot.physical_truth(first.timestamp_s)
    assert truth.linear_velocity_m_per_s[0] == pytest.approx(0.5 * DT)
    assert truth.linear_acceleration_m_per_s2[0] == pytest.approx(0.5)
    assert truth.position_m[0] == pytest.approx(0.05 + 0.25 * DT**2)


# --- sample-and-hold --------------------------------------------------------------------------


def test_truth_between_steps_is_sample_and_hold():
    robot, _ = robot_and_sensor(acceleration_m_per_s2=0.4)
    before = robot.physical_truth(0.0)
    home = scene().region.to_region().center_m
    np.testing.assert_allclose(before.position_m[:2], home)
    assert robot.truth_time_s == 0.0
    movement = ExploratoryMovement((0.05, 0.45), (0.15, 0.45))
    robot.begin(movement)
    origin = robot.physical_truth(0.0)
    np.testing.assert_allclose(origin.position_m, [0.05, 0.45, 0.1 - 0.044])
    np.testing.assert_array_equal(origin.force_n, 0.0)
    np.testing.assert_array_equal(origin.linear_velocity_m_per_s, 0.0)
    states = [robot.step() for _ in range(30)]
    assert robot.truth_time_s == states[-1].timestamp_s
    times = [s.timestamp_s for s in states]
    at_steps = [robot.physical_truth(t) for t in times]
    for k in range(len(times) - 1):
        for fraction in (0.0, 0.3, 0.999):
            held = robot.physical_truth(times[k] + fraction * (times[k + 1] - times[k]))
            assert same(held, at_steps[k])
            assert held.timestamp_s == times[k]
    assert same(robot.physical_truth(times[-1] + 10.0), at_steps[-1])
    assert robot.physical_truth(times[0] - 1e-6).timestamp_s == 0.0  # before the first step
    # The truth follows the logs the robot already keeps.
    g = robot.ground_truth
    np.testing.assert_array_equal([t.position_m[:2] for t in at_steps], g.positions_m)
    np.testing.assert_array_equal([t.force_n[:2] for t in at_steps], g.forces_n)
    # A new movement's begin changes nothing already stepped: it shows at its first step.
    last = robot.physical_truth(robot.truth_time_s)
    robot.begin(ExploratoryMovement((0.5, 0.1), (0.6, 0.1)))
    assert same(robot.physical_truth(robot.truth_time_s), last)


# --- the inertial and wrench numbers ----------------------------------------------------------


def test_inertial_load_orientation_and_torque():
    mass, accel, height = 1.3, 0.4, 0.12
    robot, _ = robot_and_sensor(
        end_effector_mass_kg=mass, acceleration_m_per_s2=accel, sensor_height_m=height
    )
    movement = ExploratoryMovement((0.05, 0.05), (0.05, 0.20), speed_m_per_s=0.05)  # along +y
    states = steps(robot, movement)
    records = [robot.physical_truth(s.timestamp_s) for s in states]
    ramp = round(0.05 / accel / DT)  # 12.5 steps: steps 0..11 wholly accelerating
    for truth in records:
        assert truth.end_effector_mass_kg == mass
        np.testing.assert_allclose(
            truth.orientation_wxyz, [math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]
        )
        np.testing.assert_array_equal(truth.angular_velocity_rad_per_s, 0.0)
        assert truth.position_m[2] == pytest.approx(height - 0.044)
        # Torque of the force acting at the fingertip about the sensor origin.
        fingertip = truth.position_m - [0.0, 0.0, height]
        np.testing.assert_allclose(
            truth.torque_nm, np.cross(fingertip - truth.position_m, truth.force_n), atol=1e-14
        )
    # In the tool frame the tool accelerates along its own x: inertial force m a along +x,
    # then -m a while stopping; the specific force (DESIGN §2) adds gravity's reaction on z.
    first, last = records[0], records[-1]
    r = first.rotation_matrix
    np.testing.assert_allclose(r @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-15)
    np.testing.assert_allclose(
        mass * r.T @ first.linear_acceleration_m_per_s2, [mass * accel, 0, 0], atol=1e-12
    )
    gravity = np.array([0.0, 0.0, -STANDARD_GRAVITY])
    np.testing.assert_allclose(
        r.T @ (first.linear_acceleration_m_per_s2 - gravity), [accel, 0, STANDARD_GRAVITY],
        atol=1e-12,
    )
    assert all(t.linear_acceleration_m_per_s2[1] == pytest.approx(accel) for t in records[:ramp])
    np.testing.assert_allclose(
        mass * last.rotation_matrix.T @ last.linear_acceleration_m_per_s2,
        [-mass * accel * 0.5, 0, 0],  # the last step holds half a step of stopping (12.5 steps)
        atol=1e-12,
    )
    # In free raking the sand pushes against the motion.
    mid = records[len(records) // 2]
    assert mid.force_n[1] < 0 and mid.force_n @ mid.linear_velocity_m_per_s < 0
    assert mid.torque_nm[0] == pytest.approx(height * mid.force_n[1])


# --- rewind and the kit -----------------------------------------------------------------------


def test_rewind_restores_the_truth():
    robot, _ = robot_and_sensor(acceleration_m_per_s2=0.5)
    robot.begin(ExploratoryMovement((0.1, 0.25), (0.34, 0.25)))
    for _ in range(5):
        robot.step()
    checkpoint = robot.checkpoint()
    time_at_checkpoint = robot.truth_time_s
    at_checkpoint = robot.physical_truth(time_at_checkpoint)
    first = [robot.step() for _ in range(20)]
    first_truth = [robot.physical_truth(s.timestamp_s) for s in first]
    robot.rewind(checkpoint)
    assert robot.truth_time_s == time_at_checkpoint
    assert same(robot.physical_truth(first[-1].timestamp_s), at_checkpoint)  # later steps gone
    again = [robot.step() for _ in range(20)]
    assert [s.timestamp_s for s in again] == [s.timestamp_s for s in first]
    for a, b in zip(first_truth, [robot.physical_truth(s.timestamp_s) for s in again], strict=True):
        assert same(a, b)


@pytest.mark.parametrize(
    "config",
    # The kit allows 0.5 s beyond a movement's length / speed, so v / a must stay below it.
    [{"acceleration_m_per_s2": 0.5}, {"acceleration_m_per_s2": 3.0, "end_effector_mass_kg": 2.0}],
)
def test_the_robot_with_a_speed_profile_passes_the_kit(config):
    (spec,) = sandbox_plugin.hapticframe_robots()
    spec = dataclasses.replace(spec, check_config=config)
    results = run_checks(spec)
    assert results and all(r.status == "PASS" for r in results), [
        (r.check, r.status, r.message) for r in results if r.status != "PASS"
    ]


def test_the_documented_sensor_physics_removes_the_sandbox_inertia():
    # The snippet of docs/simulated-devices.md, run on the sandbox's truth: the F/T reading
    # holds m (a + g) in the tool frame, and the observer's Eq. 3.10 recovers the force.
    doc = (Path(__file__).resolve().parents[2] / "docs" / "simulated-devices.md").read_text()
    snippet = re.findall(r"```python\n(.*?)```", doc, re.S)[1]
    namespace: dict = {}
    exec(snippet, namespace)
    mass, accel = 0.8, 0.5
    robot, _ = robot_and_sensor(acceleration_m_per_s2=accel)
    states = steps(robot, ExploratoryMovement((0.05, 0.05), (0.25, 0.15)))
    first = robot.physical_truth(states[0].timestamp_s)
    r_ti = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # IMU yawed 90 deg
    offset = np.array([0.5, -0.2, 1.0])
    force, torque = namespace["ft_readings"](first, r_ti, offset)
    r_wt = first.rotation_matrix
    np.testing.assert_allclose(
        force - r_wt.T @ first.force_n - offset, [mass * accel, 0, mass * STANDARD_GRAVITY],
        atol=1e-12,
    )
    np.testing.assert_allclose(torque, r_wt.T @ first.torque_nm, atol=1e-15)
    for state in states[::7]:
        truth = robot.physical_truth(state.timestamp_s)
        force, _ = namespace["ft_readings"](truth, r_ti, offset)
        a_imu = namespace["imu_readings"](truth, r_ti)["acceleration_m_per_s2"]
        np.testing.assert_allclose(
            force - mass * r_ti @ a_imu - offset, truth.rotation_matrix.T @ truth.force_n,
            atol=1e-12,
        )
