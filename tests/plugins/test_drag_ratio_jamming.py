"""The drag-ratio jamming classifier: its arithmetic at the extremes, streaming, transfer
between the two worlds, and the fit / save / load round trip."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import hapticframe_mpm_sand
from hapticframe import Circle, Scene
from hapticframe.kinds import BuildContext, ExploratoryMovement, SampleBatch
from hapticframe_jamming import (
    DragRatioJammingClassifier,
    DragRatioJammingConfig,
    DragTracker,
    calibrate_drag_ratio,
)
from hapticframe_jamming._drag_functional import DragSettings, alarm_onsets
from hapticframe_mpm_sand import MpmSandRobot, MpmSandRobotConfig
from hapticframe_sandbox import SandboxRobot, SandboxRobotConfig

RATE_HZ = 100.0


def _classifier(**config: object) -> DragRatioJammingClassifier:
    return DragRatioJammingClassifier(
        DragRatioJammingConfig(**config), BuildContext(id="jamming", rng=np.random.default_rng(0))
    )


def _batch(force: np.ndarray, valid: np.ndarray | None = None) -> SampleBatch:
    force = np.asarray(force, dtype=np.float64)
    t = np.arange(len(force)) / RATE_HZ
    values = np.stack([force, np.zeros_like(force)], axis=1)
    if valid is None:
        return SampleBatch(t, {"force_n": values})
    return SampleBatch(t, {"force_n": values}, valid={"force_n": valid})


def _settings(**changes: float) -> DragSettings:
    base = dict(settle_window_s=0.25, settle_fraction=0.04, warmup_min_s=0.8, warmup_max_s=2.5,
                tracking_time_s=1.5, min_drag=0.05, max_dt_s=0.05, drift=0.12)
    base.update(changes)
    return DragSettings(**base)


# --- the arithmetic at the extremes -------------------------------------------------------


def test_a_constant_drag_is_estimated_and_never_alarms():
    tracker = DragTracker(_settings())
    out = [tracker.step(k / RATE_HZ, 3.0, 0.0) for k in range(500)]
    armed = [o[0] for o in out]
    assert not armed[0] and armed[-1]
    assert tracker.drag == pytest.approx(3.0)
    assert max(o[3] for o in out) == 0.0  # the CUSUM never leaves 0
    # armed once the minimum warm-up (and two windows) passed on a settled force
    assert armed.index(True) == pytest.approx(0.8 * RATE_HZ, abs=1)


@pytest.mark.parametrize("force", [0.0, -1.0, 1e-12])
def test_a_drag_near_zero_is_floored_and_stays_finite(force):
    tracker = DragTracker(_settings())
    out = [tracker.step(k / RATE_HZ, force, 0.0) for k in range(400)]
    assert tracker.drag == pytest.approx(0.05)
    assert all(np.isfinite(v) for o in out for v in o[1:])


def test_a_sustained_rise_accumulates_and_a_blip_is_forgotten():
    tracker = DragTracker(_settings())
    for k in range(150):
        tracker.step(k / RATE_HZ, 2.0, 0.0)
    # a one-sample spike of 3x: log 3 - 0.12 = 0.98 over 10 ms, then forgotten
    _, _, _, spike = tracker.step(1.5, 6.0, 0.0)
    assert spike == pytest.approx((np.log(3.0) - 0.12) / RATE_HZ)
    later = [tracker.step(1.5 + k / RATE_HZ, 2.0, 0.0)[3] for k in range(1, 20)]
    assert later[-1] == 0.0
    # a rise to 1.5x held for 0.5 s: CUSUM (log 1.5 - 0.12) x 0.5 s, the drag frozen
    drag = tracker.drag
    for k in range(50):
        cusum = tracker.step(1.7 + k / RATE_HZ, 3.0, 0.0)[3]
    assert tracker.drag == drag
    assert cusum == pytest.approx((np.log(1.5) - 0.12) * 0.5, rel=0.03)


def test_a_ramp_that_never_settles_is_estimated_at_the_latest_warm_up():
    tracker = DragTracker(_settings())
    armed = [tracker.step(k / RATE_HZ, 1.0 + k, 0.0)[0] for k in range(400)]
    # estimated at the sample at 2.5 s, armed from the next one
    assert armed.index(True) == int(2.5 * RATE_HZ) + 1


def test_alarm_onsets_count_rising_edges_where_counted():
    flagged = np.array([0, 1, 1, 0, 1, 0, 1, 1], dtype=bool)
    counted = np.array([1, 1, 1, 1, 0, 1, 1, 1], dtype=bool)
    assert alarm_onsets(flagged, counted) == 2
    assert alarm_onsets(np.zeros(0, dtype=bool), np.zeros(0, dtype=bool)) == 0


@pytest.mark.parametrize("n", [1, 2, 300])
def test_nan_single_samples_and_huge_forces_give_valid_probabilities(n):
    clf = _classifier()
    force = np.full(n, 1e30)
    force[::2] = np.nan
    probs = clf.predict_proba(_batch(force)).probabilities
    assert probs.shape == (n, 3)
    assert np.all(np.isfinite(probs))
    assert np.allclose(probs.sum(axis=1), 1.0)
    # before any valid sample: uniform, arg-max free
    assert np.allclose(probs[0], 1 / 3)


def test_invalid_samples_are_held_not_read():
    force = np.full(400, 2.0)
    valid = np.ones(400, dtype=bool)
    valid[200:210] = False
    force[200:210] = 500.0  # what an invalid sample may hold: never read
    probs = _classifier().predict_proba(_batch(force, valid)).probabilities
    assert np.all(probs.argmax(axis=1) == 0)


def test_streaming_in_any_chunking_equals_the_batch_bit_for_bit():
    rng = np.random.default_rng(5)
    force = np.concatenate([np.full(200, 2.0), np.linspace(2.0, 5.0, 100), np.full(50, 40.0)])
    batch = _batch(force + 0.05 * rng.standard_normal(force.size))
    clf = _classifier()
    whole = clf.predict_proba(batch).probabilities
    clf.reset()
    parts, start = [], 0
    for size in rng.integers(1, 30, size=200):
        if start >= len(batch):
            break
        parts.append(clf.update(batch.select(slice(start, start + int(size)))).probabilities)
        start += int(size)
    assert np.array_equal(np.concatenate(parts), whole)
    labels = whole.argmax(axis=1)
    assert labels[150] == 0 and 1 in labels[200:300] and 2 in labels[300:]


def test_one_component_is_read_when_configured():
    force = np.concatenate([np.full(200, 2.0), np.full(100, 4.0)])
    batch = SampleBatch(np.arange(300) / RATE_HZ,
                        {"force_n": np.stack([np.full(300, 2.0), force], axis=1)})
    along_x = _classifier(force_component="0").predict(batch)
    along_y = _classifier(force_component="1").predict(batch)
    assert np.all(along_x == 0) and np.any(along_y[200:] == 1)
    with pytest.raises(ValueError, match="force_component 2"):
        _classifier(force_component="2").predict(batch)


# --- the same settings in both worlds ------------------------------------------------------


#: The engine world's first response library (7.5 mm, 30 ms steps): the world these
#: findings were measured in (docs/benchmarks.md, jamming detection). In the second, the
#: free drag triples over a run's first 7 cm (docs/physics-world.md) and the defaults
#: alarm in free sand (the strict xfail below).
FIRST_LIBRARY = str(Path(hapticframe_mpm_sand.__file__).parent / "data"
                    / "response-library-7.5mm-30ms.npz")


def _rake(world: str, depth: float, with_object: bool, seed: int) -> tuple[SampleBatch, np.ndarray,
                                                                          np.ndarray]:
    objects = [Circle(center_m=(0.40, 0.25), radius_m=0.03)] if with_object else [
        Circle(center_m=(0.70, 0.45), radius_m=0.02)]
    context = BuildContext(id="arm", rng=np.random.default_rng(seed), scene=Scene(objects=objects))
    robot: SandboxRobot
    if world == "sandbox":
        robot = SandboxRobot(SandboxRobotConfig(depth_m=depth), context)
    else:
        library = FIRST_LIBRARY if world == "mpm-sand" else None  # "mpm-sand-2": the bundled
        robot = MpmSandRobot(MpmSandRobotConfig(depth_m=depth, library_path=library), context)
    robot.begin(ExploratoryMovement((0.05, 0.25), (0.45 if with_object else 0.60, 0.25),
                                    speed_m_per_s=0.05, depth_m=depth))
    while robot.step() is not None:
        pass
    truth = robot.ground_truth
    noise = 0.3 * np.random.default_rng(seed + 1).standard_normal(truth.forces_n.shape)
    return (SampleBatch(truth.timestamps_s, {"force_n": truth.forces_n + noise}), truth.states,
            truth.positions_m[:, 0])


@pytest.mark.parametrize("world", ["sandbox", "mpm-sand"])
def test_the_default_settings_detect_jamming_before_contact_in_both_worlds(world):
    """Free drags of 1 N (engine, 2 cm) to 16 N (sandbox, 4.4 cm), rises of x1.3 to x4: the
    same ratio settings flag each approach while the truth is jamming, never free sand."""
    clf = _classifier()
    for depth in (0.044, 0.02):
        batch, states, _x = _rake(world, depth, True, seed=3)
        labels = clf.predict(batch)
        first = int(np.flatnonzero(labels != 0)[0])
        assert states[first] == 1, (world, depth, states[first])
        free, _, _ = _rake(world, depth, False, seed=4)
        assert np.all(clf.predict(free) == 0), (world, depth)


@pytest.mark.xfail(strict=True, reason="the second library's free drag keeps rising over a "
                   "run's first 7 cm (the surcharge in the engine's small bed); the warm-up "
                   "estimate lags it and the defaults alarm in free sand at 2 cm depth")
def test_the_defaults_stay_quiet_in_free_sand_of_the_second_library():
    clf = _classifier()
    free, _, _ = _rake("mpm-sand-2", 0.02, False, seed=4)
    assert np.all(clf.predict(free) == 0)


def test_the_old_absolute_thresholds_do_not_transfer_to_the_engine_world():
    """The baseline the new classifier is for: force-rate-jamming's sandbox thresholds see
    the engine's jamming only at contact."""
    from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig

    old = ForceRateJammingClassifier(ForceRateJammingConfig(),
                                     BuildContext(id="j", rng=np.random.default_rng(0)))
    batch, states, _x = _rake("mpm-sand", 0.029, True, seed=3)
    first = int(np.flatnonzero(old.predict(batch) != 0)[0])
    assert states[first] == 2


# --- fit, save, load ----------------------------------------------------------------------


def test_fit_meets_the_false_alarm_budget_and_round_trips(tmp_path):
    recordings = [_rake("mpm-sand", d, obj, seed=s) for d in (0.044, 0.029)
                  for obj in (True, False) for s in (11,)]
    batches = [r[0] for r in recordings]
    labels = [r[1] for r in recordings]
    clf = _classifier()
    clf.fit(batches, labels)
    report = clf.training_report()
    assert report["budget_met"] and report["false_alarms_per_m"] <= 1.0
    assert report["approaches"] == 2 and report["early"] == 2
    clf.save(tmp_path)
    loaded = _classifier(model_dir=str(tmp_path))
    for key in ("drift", "cusum_threshold", "contact_ratio", "contact_ratio_rate_per_s",
                "warmup_min_s"):
        assert getattr(loaded.config, key) == getattr(clf.config, key)
    assert loaded.training_report() == report
    assert np.array_equal(loaded.predict_proba(batches[0]).probabilities,
                          clf.predict_proba(batches[0]).probabilities)
    # another filter than the one fitted through is refused, naming the file
    with pytest.raises(ValueError, match="cutoff_hz"):
        _classifier(model_dir=str(tmp_path), cutoff_hz=5.0)
    record = json.loads((tmp_path / "drag_ratio.json").read_text())
    record["thresholds"]["drift"] = "0.1"
    (tmp_path / "drag_ratio.json").write_text(json.dumps(record))
    with pytest.raises(ValueError, match=r"drag_ratio\.json"):
        _classifier(model_dir=str(tmp_path))


def test_fit_refuses_labels_it_cannot_use():
    batch = _batch(np.full(100, 2.0))
    with pytest.raises(ValueError, match="free"):
        calibrate_drag_ratio([batch], [np.zeros(100)])
    with pytest.raises(ValueError, match="shape"):
        calibrate_drag_ratio([batch], [np.zeros(99)])
    with pytest.raises(ValueError, match="at least one"):
        calibrate_drag_ratio([], [])


# --- the drag carried from one movement to the next -----------------------------------------


def _ramp_from_rest(peak: float, samples: int) -> np.ndarray:
    """A movement that starts next to an object: the force climbs from rest, no plateau."""
    return np.linspace(0.0, peak, samples)


def test_a_carried_drag_arms_the_next_warm_up_and_forget_drops_it():
    tracker = DragTracker(_settings())
    for k in range(300):
        tracker.step(k / RATE_HZ, 4.0, 0.0)
    tracker.end_movement()
    assert tracker.prior == pytest.approx(4.0) and tracker.drag is None
    out = [tracker.step(k / RATE_HZ, f, 0.0) for k, f in enumerate(_ramp_from_rest(40.0, 60))]
    assert all(o[0] for o in out)  # judged against the prior from the first sample
    assert out[-1][3] > 0.02  # the CUSUM on log(f / 4 N) passed its level
    tracker.end_movement()  # no drag of its own: the prior stays the largest seen
    assert tracker.prior == pytest.approx(4.0)
    tracker.forget()
    assert tracker.prior is None
    assert not tracker.step(0.0, 10.0, 0.0)[0]


def test_the_prior_is_the_largest_drag_so_far():
    tracker = DragTracker(_settings())
    for level in (6.0, 2.0):
        for k in range(300):
            tracker.step(k / RATE_HZ, level, 0.0)
        tracker.end_movement()
    assert tracker.prior == pytest.approx(6.0)


def _movement_end(classifier: DragRatioJammingClassifier) -> None:
    from hapticframe.kinds import MovementResult

    movement = ExploratoryMovement(np.zeros(2), np.ones(2))
    classifier.on_movement_end(MovementResult(0, movement, False, "", None))


@pytest.mark.parametrize("carry", [True, False])
def test_a_movement_starting_at_an_object_is_flagged_only_with_the_carried_drag(carry):
    classifier = _classifier(carry_drag=carry)
    classifier.update(_batch(np.full(300, 5.0)))  # free raking: the drag, 5 N
    _movement_end(classifier)
    classifier.reset()  # the run loop resets at every movement's start
    ramp = _ramp_from_rest(60.0, 80)  # 0.8 s: within the warm-up of its own drag
    flagged = []
    for k in range(len(ramp)):
        t = np.array([k / RATE_HZ])
        out = classifier.update(SampleBatch(t, {"force_n": np.array([[ramp[k], 0.0]])}))
        flagged.append(int(np.argmax(out.probabilities)) != 0)
    assert any(flagged) is carry
    if carry:  # not before the force passed the carried drag
        assert ramp[flagged.index(True)] > 5.0


def test_trace_starts_fresh_and_leaves_the_carried_drag_alone():
    classifier = _classifier()
    classifier.update(_batch(np.full(300, 5.0)))
    _movement_end(classifier)
    before = classifier.checkpoint()
    fresh = classifier.trace(_batch(_ramp_from_rest(60.0, 80)))
    assert not fresh.armed.any()  # no carried drag in a trace
    assert classifier.checkpoint()[1] == before[1]
    assert classifier.checkpoint()[1].prior == pytest.approx(5.0)
