"""The sandbox robot (world simulator) and its force sensor, driven without the run loop."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hapticframe import Circle, Kind, RobotSpec, Scene, SensorSpec
from hapticframe.kinds import BuildContext, ExploratoryMovement, MovementResult, RunOutcome
from hapticframe_granular import rupture_distance
from hapticframe_sandbox import (
    SandboxForceSensor,
    SandboxForceSensorConfig,
    SandboxRobot,
    SandboxRobotConfig,
    approach_movement,
    record_movements,
)
from hapticframe_sandbox import _functional as F
from hapticframe_sandbox import plugin as sandbox_plugin

CENTRE = (0.3, 0.25)
RADIUS = 0.04


def circle_scene() -> Scene:
    return Scene(objects=[Circle(center_m=CENTRE, radius_m=RADIUS)])


def build(seed: int = 0, scene: Scene | None = None, noise: float = 0.3, **robot_cfg):
    scene = circle_scene() if scene is None else scene
    robot = SandboxRobot(
        SandboxRobotConfig(**robot_cfg),
        BuildContext(id="arm", rng=np.random.default_rng(seed), scene=scene),
    )
    sensor = SandboxForceSensor(
        SandboxForceSensorConfig(noise_std_n=noise),
        BuildContext(id="ft", rng=np.random.default_rng(seed + 1000), inputs={"arm": robot}),
    )
    return robot, sensor


def straight_at_circle(offset: float = 0.0, standoff: float = 0.2) -> ExploratoryMovement:
    """From the left, along y = centre + offset, ending at the circle's far side."""
    y = CENTRE[1] + offset
    return ExploratoryMovement((CENTRE[0] - RADIUS - standoff, y), (CENTRE[0] + RADIUS, y))


def miss() -> ExploratoryMovement:
    """A movement far from the object."""
    return ExploratoryMovement((0.05, 0.45), (0.6, 0.45))


def result_for(robot: SandboxRobot, index: int, movement: ExploratoryMovement) -> MovementResult:
    return MovementResult(index, movement, bool(robot.halt_reason), robot.halt_reason, robot.state)


def run(robot: SandboxRobot, movement: ExploratoryMovement, sensor=None):
    robot.begin(movement)
    states, batches = [], []
    while (state := robot.step()) is not None:
        states.append(state)
        if sensor is not None:
            batches.append(sensor.read())
    return states, batches


# --- construction and registration -------------------------------------------------------


def test_robot_needs_a_scene_and_names_itself():
    with pytest.raises(ValueError, match=r"'arm'.*scene"):
        SandboxRobot(SandboxRobotConfig(), BuildContext(id="arm", rng=np.random.default_rng(0)))


def test_sensor_needs_exactly_one_sandbox_robot():
    robot, _ = build()
    rng = np.random.default_rng(0)
    cfg = SandboxForceSensorConfig()
    with pytest.raises(ValueError, match="'ft'"):
        SandboxForceSensor(cfg, BuildContext(id="ft", rng=rng))
    with pytest.raises(ValueError, match="'ft'"):
        SandboxForceSensor(cfg, BuildContext(id="ft", rng=rng, inputs={"a": robot, "b": robot}))
    other, _ = build()
    sensor = SandboxForceSensor(cfg, BuildContext(id="ft", rng=rng, inputs={"arm": other}))
    with pytest.raises(ValueError, match="'x'"):
        SandboxForceSensor(cfg, BuildContext(id="x", rng=rng, inputs={"ft": sensor}))


def test_registration_specs():
    (robot_spec,) = sandbox_plugin.hapticframe_robots()
    sensor_spec, taxel_spec = sandbox_plugin.hapticframe_sensors()
    assert taxel_spec.name == "sandbox-taxels" and taxel_spec.inputs == (Kind.ROBOT,)
    assert isinstance(robot_spec, RobotSpec) and robot_spec.name == "sandbox"
    assert robot_spec.capabilities == {"simulated", "needs-scene"}
    assert robot_spec.load_factory() is SandboxRobot
    assert isinstance(sensor_spec, SensorSpec) and sensor_spec.name == "sandbox-force"
    assert sensor_spec.capabilities == {"simulated", "needs-robot"}
    assert sensor_spec.inputs == (Kind.ROBOT,)
    assert sensor_spec.load_factory() is SandboxForceSensor


def test_registration_module_is_import_light():
    code = (
        "import sys, hapticframe_sandbox.plugin, hapticframe_sandbox;"
        "heavy = [m for m in ('hapticframe_sandbox._robot', 'hapticframe_sandbox._sensor',"
        " 'matplotlib') if m in sys.modules];"
        "print(heavy); sys.exit(1 if heavy else 0)"
    )
    plugins = str(Path(__file__).resolve().parents[2] / "plugins")
    env_path = [plugins, str(Path(__file__).resolve().parents[2])]
    proc = subprocess.run(
        [sys.executable, "-c", code],
        check=False,
        env={"PYTHONPATH": ":".join(env_path)},
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_channels_of_the_sensor():
    _, sensor = build()
    info = sensor.channels["force_n"]
    assert (info.shape, info.unit, info.rate_hz) == ((2,), "N", 100.0)


# --- kinematics and time --------------------------------------------------------------------


def test_constant_speed_depth_and_heading():
    robot, _ = build()
    movement = ExploratoryMovement((0.05, 0.45), (0.15, 0.45), speed_m_per_s=0.05)
    states, _ = run(robot, movement)
    assert len(states) == 200  # 10 cm at 5 cm/s, 100 Hz
    np.testing.assert_allclose(np.diff([s.position_m[0] for s in states]), 0.0005, atol=1e-12)
    np.testing.assert_allclose(states[-1].position_m, (0.15, 0.45), atol=1e-12)
    assert all(s.depth_m == pytest.approx(0.044) for s in states)
    assert all(s.heading_rad == 0.0 and s.speed_m_per_s == 0.05 for s in states)
    assert robot.step() is None and robot.step() is None


def test_movement_overrides_speed_and_depth():
    robot, _ = build()
    movement = ExploratoryMovement((0.05, 0.45), (0.05, 0.35), speed_m_per_s=0.1, depth_m=0.02)
    states, _ = run(robot, movement)
    assert len(states) == 100
    assert states[0].heading_rad == pytest.approx(-math.pi / 2)
    assert all(s.depth_m == 0.02 for s in states)
    np.testing.assert_allclose(np.diff([s.position_m[1] for s in states]), -0.001, atol=1e-12)
    # The commanded depth does not change the robot's own schedule.
    assert robot.current_depth_m == pytest.approx(0.044)


def test_timestamps_strictly_increase_across_movements():
    robot, sensor = build()
    times = []
    for movement in (
        miss(),
        straight_at_circle(),
        ExploratoryMovement((0.1, 0.1), (0.1, 0.1)),
        miss(),
    ):
        states, batches = run(robot, movement, sensor)
        times += [s.timestamp_s for s in states]
        batch_times = np.concatenate([b.timestamps_s for b in batches]) if batches else []
        np.testing.assert_array_equal(batch_times, [s.timestamp_s for s in states])
        robot.on_movement_end(result_for(robot, 0, movement))
    times = np.asarray(times)
    assert np.all(np.diff(times) > 0)
    np.testing.assert_allclose(np.diff(times), 0.01, rtol=1e-9)
    np.testing.assert_array_equal(robot.ground_truth.timestamps_s, times)


def test_zero_length_movement_ends_at_once():
    robot, sensor = build()
    robot.begin(ExploratoryMovement((0.1, 0.1), (0.1, 0.1)))
    assert robot.step() is None
    assert len(sensor.read()) == 0


def test_halt_stops_and_keeps_the_first_reason():
    robot, _ = build()
    robot.begin(miss())
    for _ in range(5):
        robot.step()
    robot.halt("interaction")
    robot.halt("something else")
    assert robot.step() is None
    assert robot.halt_reason == "interaction"
    robot.begin(miss())
    assert robot.halt_reason == ""
    assert robot.step() is not None


# --- determinism --------------------------------------------------------------------------


def _forces(seed: int):
    robot, sensor = build(seed)
    _, batches = run(robot, straight_at_circle(offset=0.01), sensor)
    return np.concatenate([b.channels["force_n"] for b in batches]), robot.ground_truth


def test_seeded_runs_are_identical_and_seeds_matter():
    a, truth_a = _forces(3)
    b, truth_b = _forces(3)
    c, _ = _forces(4)
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(truth_a.forces_n, truth_b.forces_n)
    np.testing.assert_array_equal(truth_a.states, truth_b.states)
    n = min(len(a), len(c))
    assert not np.allclose(a[:n], c[:n])


# --- the physics ---------------------------------------------------------------------------


def test_free_drag_is_fig_3_6_sized_and_opposes_motion():
    robot, _ = build(scene=Scene())
    run(robot, ExploratoryMovement((0.0, 0.25), (0.6, 0.25)))
    truth = robot.ground_truth
    steady = truth.force_magnitude_n[200:]  # after the failure zone has developed
    assert 10.0 < steady.mean() < 20.0
    assert 0.02 < steady.std() / steady.mean() < 0.25  # it fluctuates, but not wildly
    assert np.all(truth.forces_n[:, 0] <= 0.0)  # moving +x, the force points -x
    assert np.all(truth.states == 0)
    # Shallower raking drags less, roughly with the square of depth.
    shallow, _ = build(scene=Scene(), depth_m=0.022)
    run(shallow, ExploratoryMovement((0.0, 0.25), (0.6, 0.25)))
    ratio = shallow.ground_truth.force_magnitude_n[200:].mean() / steady.mean()
    assert 0.2 < ratio < 0.3


def test_jamming_begins_one_rupture_distance_before_contact():
    robot, _ = build(noise=0.0)
    movement = straight_at_circle()
    run(robot, movement)
    truth = robot.ground_truth
    states = truth.states
    first_jam = int(np.argmax(states >= 1))
    first_contact = int(np.argmax(states == 2))
    assert 0 < first_jam < first_contact
    assert np.all(states[:first_jam] == 0)
    assert np.all(states[first_jam:first_contact] == 1)
    r = rupture_distance(0.044, math.radians(90.0), math.radians(31.5))
    gap_at_jam = CENTRE[0] - RADIUS - truth.positions_m[first_jam, 0]
    gap_at_contact = CENTRE[0] - RADIUS - truth.positions_m[first_contact, 0]
    assert gap_at_jam == pytest.approx(r, abs=1e-3)
    assert gap_at_contact == pytest.approx(0.0, abs=1e-3)
    # A surge in force and force rate while jamming, steeper still at contact.
    force = truth.force_magnitude_n
    rate = np.diff(force) * 100.0
    free_level = force[first_jam - 50 : first_jam].mean()
    assert force[first_contact - 1] > free_level + 30.0
    late_jam_rate = np.mean(rate[first_contact - 30 : first_contact - 1])
    free_rate = np.mean(np.abs(rate[first_jam - 60 : first_jam - 1]))
    contact_rate = np.mean(rate[first_contact : first_contact + 5])
    assert late_jam_rate > 3 * free_rate
    assert contact_rate > 1.5 * late_jam_rate


def test_off_axis_object_pushes_sideways():
    robot, _ = build(noise=0.0)
    run(robot, straight_at_circle(offset=-0.03))  # the object lies to the left (+y side)
    truth = robot.ground_truth
    jam = truth.states == 1
    assert jam.any()
    assert np.mean(truth.forces_n[jam, 1]) < 0  # pushed back away from the object (-y)


def test_force_limit_halts_the_robot():
    robot, _ = build()
    run(robot, straight_at_circle())
    assert robot.halt_reason == "force_limit"
    force = robot.ground_truth.force_magnitude_n
    assert force[-1] > 80.0 and np.all(force[:-1] <= 80.0)
    assert robot.step() is None
    # A lower limit halts during free movement.
    low, _ = build(force_limit_n=5.0, scene=Scene())
    states, _ = run(low, miss())
    assert low.halt_reason == "force_limit" and len(states) < 1100


def test_depth_schedule_shrinks_after_interacting_movements_only():
    robot, sensor = build()
    plan = [
        miss(),
        straight_at_circle(),
        miss(),
        straight_at_circle(),
        straight_at_circle(),
        miss(),
        straight_at_circle(),
        # Passes beside the object: the failure zone reaches it (jamming), the plate does not.
        straight_at_circle(offset=RADIUS + 0.015),
    ]
    record_movements(robot, sensor, plan)
    assert [m.max_state for m in robot.movements][-2:] == [2, 1]
    depths_cm = [round(100 * m.depth_m, 6) for m in robot.movements]
    assert depths_cm == [4.4, 4.4, 3.4, 3.4, 2.9, 2.65, 2.65, 2.525]
    assert [m.interacted for m in robot.movements] == [
        False,
        True,
        False,
        True,
        True,
        False,
        True,
        True,
    ]
    assert robot.current_depth_m == pytest.approx(0.024625)
    # η = (50 + 7n)° with n completed pairs of interactions.
    assert [m.side_crescent_angle_deg for m in robot.movements] == pytest.approx(
        [50, 50, 50, 50, 57, 57, 57, 64], abs=1e-12
    )


def test_movement_end_books_each_movement_once():
    robot, _ = build()
    run(robot, straight_at_circle())
    result = result_for(robot, 0, straight_at_circle())
    robot.on_movement_end(result)
    robot.on_movement_end(result)
    assert len(robot.movements) == 1
    assert robot.current_depth_m == pytest.approx(0.034)
    # Without on_movement_end, the next begin books the previous movement.
    run(robot, straight_at_circle())
    robot.begin(miss())
    assert len(robot.movements) == 2
    assert robot.current_depth_m == pytest.approx(0.029)


# --- sensor --------------------------------------------------------------------------------


def test_sensor_reads_what_the_robot_did_since_the_last_read():
    robot, sensor = build(noise=0.0)
    assert len(sensor.read()) == 0
    robot.begin(miss())
    for _ in range(3):
        robot.step()
    batch = sensor.read()
    assert len(batch) == 3 and batch.channels["force_n"].shape == (3, 2)
    truth = robot.ground_truth
    np.testing.assert_array_equal(batch.channels["force_n"], truth.forces_n)
    np.testing.assert_array_equal(batch.timestamps_s, truth.timestamps_s)
    assert len(sensor.read()) == 0
    robot.step()
    assert len(sensor.read()) == 1


def test_sensor_noise_has_the_configured_spread():
    robot, sensor = build(noise=0.5, scene=Scene())
    _, batches = run(robot, ExploratoryMovement((0.0, 0.25), (0.7, 0.25)), sensor)
    measured = np.concatenate([b.channels["force_n"] for b in batches])
    error = measured - robot.ground_truth.forces_n
    assert error.std() == pytest.approx(0.5, rel=0.05)
    assert abs(error.mean()) < 0.03


def test_sensor_reset_skips_unread_samples():
    robot, sensor = build()
    robot.begin(miss())
    robot.step()
    robot.step()
    sensor.reset()
    assert len(sensor.read()) == 0
    robot.step()
    assert len(sensor.read()) == 1


def test_recordings_carry_ground_truth_labels():
    robot, sensor = build(seed=5)
    rng = np.random.default_rng(1)
    recordings = record_movements(
        robot, sensor, [approach_movement(rng, circle_scene().objects[0])]
    )
    ((batch, labels),) = recordings
    assert labels.shape == (len(batch),)
    assert set(np.unique(labels)) == {0, 1, 2}
    assert labels[0] == 0 and labels[-1] == 2


# --- finalize ------------------------------------------------------------------------------


def test_finalize_reports_metrics_and_writes_the_force_figure(tmp_path):
    robot, sensor = build()
    record_movements(robot, sensor, [miss(), straight_at_circle(), straight_at_circle(offset=0.02)])
    outcome = RunOutcome(tmp_path / "run", robot.context.scene, (), {"arm": robot}, 1.0)
    metrics = robot.finalize(outcome)
    truth = robot.ground_truth
    assert metrics["max_force_n"] == pytest.approx(truth.force_magnitude_n.max())
    assert metrics["max_force_n"] > 80.0
    assert metrics["object_interactions"] == 2
    png = tmp_path / "run" / "forces.png"
    assert png.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_one_step_reads_equal_the_array_path():
    """A read after every step (plain floats) gives the true force plus the same draws."""
    robot, sensor = build(seed=5, noise=0.4)
    draws = np.random.default_rng(5 + 1000)  # the sensor's generator, replayed
    robot.begin(straight_at_circle(standoff=0.1))
    steps = 0
    while robot.step() is not None:
        batch = sensor.read()
        t, force = robot.true_forces_since(robot.steps_taken - 1)
        expected = force + 0.4 * draws.standard_normal(force.shape)
        np.testing.assert_array_equal(batch.timestamps_s, t)
        np.testing.assert_array_equal(batch.channels["force_n"], expected)
        steps += 1
    assert steps > 100
    # Several steps at once take the array path and continue the same stream of draws.
    robot.begin(miss())
    for _ in range(3):
        robot.step()
    t, force = robot.true_forces_since(robot.steps_taken - 3)
    np.testing.assert_array_equal(
        sensor.read().channels["force_n"], force + 0.4 * draws.standard_normal(force.shape)
    )


def test_an_object_behind_the_plate_is_skipped_exactly():
    # Raking away from an object that starts just behind the plate: the quick "behind" test
    # skips the sector sampling, which must agree with what sampling would have found.
    start = (CENTRE[0] + RADIUS + 0.002, CENTRE[1])
    away = ExploratoryMovement(start, (start[0] + 0.2, start[1]))
    robot, _ = build(noise=0.0)
    run(robot, away)
    assert np.all(robot.ground_truth.states == 0)
    eta = np.radians(90.0)  # the widest fan the robot ever samples
    angles = np.linspace(-eta, eta, 21)
    radii = np.linspace(0.0, rupture_distance(0.044, math.pi / 2, math.radians(31.5)), 40)
    sampled = F.first_hit_distances(np.array(start), angles, radii, circle_scene().occupied)
    assert np.all(np.isinf(sampled))
    edge = F.plate_edge_points(start, 0.0, 0.02)
    assert not circle_scene().occupied(edge).any()
    # Raking towards it from the same distance in front does interact.
    towards = ExploratoryMovement((CENTRE[0] - RADIUS - 0.002, CENTRE[1]),
                                  (CENTRE[0] - 0.2, CENTRE[1]))
    ahead, _ = build(noise=0.0)
    run(ahead, ExploratoryMovement(towards.start_m, towards.start_m + np.array([0.01, 0.0])))
    assert ahead.ground_truth.states[0] >= 1


def test_rewind_replays_a_movement_exactly_and_only_within_it():
    robot, sensor = build()
    robot.begin(straight_at_circle())
    for _ in range(40):
        robot.step()
        sensor.read()
    snapshot = robot.checkpoint(), sensor.checkpoint()
    first = [(robot.step(), sensor.read()) for _ in range(300)]
    robot.rewind(snapshot[0])
    sensor.rewind(snapshot[1])
    again = [(robot.step(), sensor.read()) for _ in range(300)]
    for (s1, b1), (s2, b2) in zip(first, again, strict=True):
        assert (s1 is None) == (s2 is None)
        if s1 is not None:
            assert s1.timestamp_s == s2.timestamp_s and np.array_equal(s1.position_m, s2.position_m)
        assert np.array_equal(b1.channels["force_n"], b2.channels["force_n"])
    assert len(robot.ground_truth) == 340 or robot.halt_reason
    robot.begin(miss())
    with pytest.raises(ValueError, match="not from this movement"):
        robot.rewind(snapshot[0])
