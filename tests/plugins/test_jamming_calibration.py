"""Threshold calibration from labelled runs, and detection on the simulated sandbox."""

from __future__ import annotations

import numpy as np
import pytest

from hapticframe import Circle, Ellipse, Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement, MovementResult
from hapticframe_jamming import (
    ForceRateJammingClassifier,
    ForceRateJammingConfig,
    calibrate_thresholds,
    evaluate_detection,
)
from hapticframe_jamming import _functional as F
from hapticframe_sandbox import (
    SandboxForceSensor,
    SandboxForceSensorConfig,
    SandboxRobot,
    SandboxRobotConfig,
    approach_movement,
    record_movements,
)


def make(config: ForceRateJammingConfig | None = None) -> ForceRateJammingClassifier:
    return ForceRateJammingClassifier(
        config or ForceRateJammingConfig(), BuildContext(id="jam", rng=np.random.default_rng(0))
    )


# --- the threshold search on synthetic, separable data ----------------------------------------


def synthetic_movements(rng: np.random.Generator, n: int = 12, with_contact: bool = True):
    """(force, rate, labels) per movement: free, then jamming, then contact, in separate boxes."""
    out = []
    for k in range(n):
        n_free, n_jam, n_contact = rng.integers(50, 120), rng.integers(10, 40), rng.integers(3, 10)
        f = [rng.uniform(0, 10, n_free), rng.uniform(15, 40, n_jam)]
        r = [rng.uniform(-20, 20, n_free), rng.uniform(30, 60, n_jam)]
        y = [np.zeros(n_free), np.ones(n_jam)]
        if with_contact:
            f.append(rng.uniform(50, 80, n_contact))
            r.append(rng.uniform(100, 150, n_contact))
            y.append(np.full(n_contact, 2))
        if k % 3 == 0:  # some movements never reach the object
            f, r, y = f[:1], r[:1], y[:1]
        # Free samples with high force but low rate, and high rate but low force: only the
        # AND of both thresholds separates them from jamming.
        f.append(rng.uniform(15, 40, 5))
        r.append(rng.uniform(-20, 20, 5))
        y.append(np.zeros(5))
        f.insert(0, rng.uniform(0, 10, 5))
        r.insert(0, rng.uniform(30, 60, 5))
        y.insert(0, np.zeros(5))
        out.append((np.concatenate(f), np.concatenate(r), np.concatenate(y).astype(int)))
    return out


def test_samples_objective_separates_separable_data():
    movements = synthetic_movements(np.random.default_rng(0))
    thresholds, score = F.best_and_thresholds(movements, objective="samples")
    assert score == pytest.approx(1.0)
    f, r, y = (np.concatenate(parts) for parts in zip(*movements, strict=True))
    np.testing.assert_array_equal(F.hard_states(f, r, thresholds), y)
    # Each axis alone would misclassify the decoy free samples; the AND does not.
    fj, rj, _, _ = thresholds
    assert 10.0 <= fj < 15.0 and 20.0 <= rj < 30.0


def test_events_objective_flags_every_approach_first_in_jamming():
    movements = synthetic_movements(np.random.default_rng(0))
    thresholds, score = F.best_and_thresholds(movements, objective="events")
    assert score == pytest.approx(1.0)
    for f, r, y in movements:
        predicted = F.hard_states(f, r, thresholds)
        assert np.all(predicted[y == 0] == 0)
        if np.any(y >= 1):
            assert y[np.argmax(predicted != 0)] == 1
        contact = y == 2
        np.testing.assert_array_equal(predicted[contact], 2)


def test_search_without_contact_keeps_base_contact_thresholds():
    movements = synthetic_movements(np.random.default_rng(1), with_contact=False)
    thresholds, _ = F.best_and_thresholds(movements, base=(0.0, 0.0, 45.0, 80.0))
    assert thresholds[2:] == (45.0, 80.0)
    thresholds, _ = F.best_and_thresholds(movements, base=(0.0, 0.0, 1.0, 1.0))
    assert thresholds[2:] == thresholds[:2]  # raised to the jamming thresholds
    thresholds, _ = F.best_and_thresholds(movements)
    assert thresholds[2:] == (np.inf, np.inf)


def test_search_is_deterministic_and_order_free():
    movements = synthetic_movements(np.random.default_rng(2))
    first = F.best_and_thresholds(movements)
    assert F.best_and_thresholds(movements) == first
    assert F.best_and_thresholds(movements[::-1]) == first


def test_event_objective_ignores_the_labels_hair_trigger():
    """Labels switch to jamming before the force shows anything; samples-BA chases that."""
    rng = np.random.default_rng(3)
    movements = []
    for _ in range(10):
        n_free, n_jam = 200, 100
        rate = np.concatenate([rng.normal(0, 6, n_free), np.linspace(0, 60, n_jam)])
        force = np.concatenate([rng.normal(12, 1, n_free), np.linspace(12, 50, n_jam)])
        labels = np.concatenate([np.zeros(n_free), np.ones(n_jam)]).astype(int)
        movements.append((force, rate, labels))
    events, events_score = F.best_and_thresholds(movements, objective="events")
    samples, _ = F.best_and_thresholds(movements, objective="samples")
    assert events_score == pytest.approx(1.0)  # no false alarm, every approach caught
    f, r, y = (np.concatenate(parts) for parts in zip(*movements, strict=True))
    free = y == 0
    assert not np.any(F.hard_states(f[free], r[free], events))
    # Per-sample accuracy buys jamming recall with false alarms that would halt a run.
    assert np.sum(F.hard_states(f[free], r[free], samples) != 0) > 0
    assert np.sum(F.hard_states(f[~free], r[~free], samples) != 0) > np.sum(
        F.hard_states(f[~free], r[~free], events) != 0
    )


@pytest.mark.parametrize(
    "movements, message",
    [
        ([(np.ones(5), np.ones(5), np.zeros(5))], "interaction"),
        ([(np.ones(5), np.ones(5), np.ones(5))], "free"),
        ([(np.ones(5), np.ones(4), np.zeros(5))], "equal length"),
        ([(np.ones(3), np.ones(3), np.array([0, 1, 3]))], "labels"),
        ([], "at least one"),
    ],
)
def test_search_rejects_bad_input(movements, message):
    with pytest.raises(ValueError, match=message):
        F.best_and_thresholds(movements)


def test_objective_must_be_known():
    with pytest.raises(ValueError, match="objective"):
        F.best_and_thresholds(synthetic_movements(np.random.default_rng(0)), objective="auc")


def test_plateau_argmax_picks_the_middle_of_a_tie():
    score = np.zeros((7, 7))
    score[1:6, 2:7] = 1.0
    assert F.plateau_argmax(score) == (3, 4)


def test_first_flag_indices_against_a_loop():
    rng = np.random.default_rng(4)
    f, r = rng.uniform(0, 10, 60), rng.uniform(0, 10, 60)
    fc, rc = np.linspace(-1, 11, 13), np.linspace(-1, 11, 9)
    got = F.first_flag_indices(f, r, fc, rc)
    for i, a in enumerate(fc):
        for j, b in enumerate(rc):
            hits = np.flatnonzero((f > a) & (r > b))
            assert got[i, j] == (hits[0] if hits.size else 60)


def test_calibration_checks_its_arguments():
    with pytest.raises(ValueError, match="label arrays"):
        calibrate_thresholds([], [np.zeros(3)])
    with pytest.raises(ValueError, match="at least one"):
        calibrate_thresholds([], [])


# --- on the simulated sandbox ------------------------------------------------------------------


def simulate(seed: int, n_scenes: int, movements_per_scene: int, n_free: int):
    """Approach runs (circles and ellipses, depth schedule running) and free movements."""
    rng = np.random.default_rng(seed)
    recordings = []
    for k in range(n_scenes):
        centre = tuple(rng.uniform([0.2, 0.15], [0.55, 0.35]))
        if k % 2:
            obj = Ellipse(
                center_m=centre,
                semi_axes_m=(0.045, 0.025),
                orientation_deg=float(rng.uniform(0, 180)),
            )
        else:
            obj = Circle(center_m=centre, radius_m=0.04)
        scene = Scene(objects=[obj])
        robot = SandboxRobot(
            SandboxRobotConfig(),
            BuildContext(id="arm", rng=np.random.default_rng(rng.integers(2**32)), scene=scene),
        )
        sensor = SandboxForceSensor(
            SandboxForceSensorConfig(),
            BuildContext(
                id="ft", rng=np.random.default_rng(rng.integers(2**32)), inputs={"arm": robot}
            ),
        )
        plan = [approach_movement(rng, obj, standoff_m=0.15) for _ in range(movements_per_scene)]
        recordings += record_movements(robot, sensor, plan)
    for k in range(n_free):
        depth = float((0.044, 0.034, 0.029, 0.0265)[k % 4])
        robot = SandboxRobot(
            SandboxRobotConfig(depth_m=depth),
            BuildContext(id="arm", rng=np.random.default_rng(rng.integers(2**32)), scene=Scene()),
        )
        sensor = SandboxForceSensor(
            SandboxForceSensorConfig(),
            BuildContext(
                id="ft", rng=np.random.default_rng(rng.integers(2**32)), inputs={"arm": robot}
            ),
        )
        y = rng.uniform(0.05, 0.45)
        recordings += record_movements(robot, sensor, [ExploratoryMovement((0.0, y), (0.4, y))])
    batches, labels = zip(*recordings, strict=True)
    return list(batches), list(labels)


@pytest.fixture(scope="module")
def training_runs():
    return simulate(seed=100, n_scenes=8, movements_per_scene=4, n_free=6)


@pytest.fixture(scope="module")
def held_out_runs():
    return simulate(seed=200, n_scenes=10, movements_per_scene=4, n_free=10)


@pytest.mark.slow
def test_default_thresholds_detect_jamming_before_contact(held_out_runs):
    report = evaluate_detection(make(), *held_out_runs)
    assert report.approaches == 40 and report.free_movements == 10
    assert report.early_fraction >= 0.9
    assert report.late == 0
    assert report.false_alarm + report.free_false_alarms <= 2
    assert report.free_sample_false_alarm_rate < 1e-3
    assert report.mean_lead_time_s > 0.3


@pytest.mark.slow
def test_calibration_from_a_bad_start_classifies_held_out_runs_well(training_runs, held_out_runs):
    bad = ForceRateJammingConfig(
        jamming_force_n=0.0, jamming_rate_n_per_s=0.0, contact_force_n=1.0, contact_rate_n_per_s=1.0
    )
    assert evaluate_detection(make(bad), *held_out_runs).early_fraction < 0.2
    classifier = make(bad)
    classifier.fit(*training_runs)
    fj, rj, fc, rc = classifier.thresholds
    assert fc >= fj and rc >= rj
    report = evaluate_detection(classifier, *held_out_runs)
    assert report.early_fraction >= 0.9
    assert report.false_alarm + report.free_false_alarms <= 2
    # Per-sample, the three states are told apart well above chance (1/3).
    truth, predicted = [], []
    for batch, labels in zip(*held_out_runs, strict=True):
        truth.append(labels)
        predicted.append(classifier.predict(batch))
    assert F.balanced_accuracy(np.concatenate(truth), np.concatenate(predicted)) > 0.7
    # Deterministic: the same data give the same thresholds.
    again = calibrate_thresholds(*training_runs, base_config=bad)
    assert again == classifier.config


@pytest.mark.slow
def test_calibrated_thresholds_are_close_to_the_defaults(training_runs):
    calibrated = calibrate_thresholds(*training_runs)
    default = ForceRateJammingConfig()
    # The defaults were set from such calibrations; the rate threshold is what separates.
    assert abs(calibrated.jamming_rate_n_per_s - default.jamming_rate_n_per_s) < 10.0
    assert calibrated.jamming_force_n < 15.0


def test_closed_loop_halts_each_approach_while_jamming():
    """The run loop's pattern: step, read, classify, halt on a non-free state."""
    rng = np.random.default_rng(9)
    obj = Circle(center_m=(0.35, 0.25), radius_m=0.04)
    robot = SandboxRobot(
        SandboxRobotConfig(),
        BuildContext(id="arm", rng=np.random.default_rng(1), scene=Scene(objects=[obj])),
    )
    sensor = SandboxForceSensor(
        SandboxForceSensorConfig(),
        BuildContext(id="ft", rng=np.random.default_rng(2), inputs={"arm": robot}),
    )
    classifier = make()
    for index in range(4):
        movement = approach_movement(rng, obj, standoff_m=0.2)
        robot.begin(movement)
        final_class = ""
        while robot.step() is not None:
            probabilities = classifier.update(sensor.read())
            final_class = classifier.classes[int(probabilities.labels[-1])]
            if final_class != "free":
                robot.halt("interaction")
        result = MovementResult(
            index, movement, True, robot.halt_reason, robot.state, final_class=final_class
        )
        robot.on_movement_end(result)
        classifier.on_movement_end(result)
        truth = robot.movements[-1]
        assert truth.halt_reason == "interaction" and final_class == "jamming"
        assert truth.max_state == 1  # halted before the plate touched the object
        assert truth.max_force_n < 80.0
    depths_cm = [round(100 * m.depth_m, 6) for m in robot.movements]
    assert depths_cm == [4.4, 3.4, 2.9, 2.65]


def test_free_drag_floor_keeps_the_jamming_threshold_above_free_drag() -> None:
    """Free drag that changes with depth: a shallow approach's jamming lies below the deep
    movement's free drag; the floor keeps the fitted threshold above that drag."""
    n = 200
    t = np.arange(n)
    deep_free = (np.full(n, 3.6), np.zeros(n), np.zeros(n, dtype=np.int64))
    ramp = np.where(t > 120, 1.0 + 0.02 * (t - 120), 1.0)
    shallow = (ramp, np.gradient(ramp) * 100, np.where(t > 120, 1, 0))
    floor = F.free_drag_floor([deep_free, shallow])
    assert floor == pytest.approx(3.6)
    (fj, _rj, _fc, _rc), _ = F.best_and_thresholds([deep_free, shallow], force_floor=floor)
    assert fj >= 3.6
    (fj_free, *_), _ = F.best_and_thresholds([deep_free, shallow])
    assert fj_free < 3.6  # without it the fit falls below the deep free drag
    with pytest.raises(ValueError, match="free-labelled"):
        F.free_drag_floor([(np.ones(3), np.zeros(3), np.ones(3, dtype=np.int64))])
