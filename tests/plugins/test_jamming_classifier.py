"""The force/force-rate jamming classifier: filtering, probabilities, streaming, extremes."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydantic import ValidationError

from hapticframe import ClassifierSpec
from hapticframe.filters import butterworth_sos
from hapticframe.kinds import BuildContext, ChannelInfo, SampleBatch
from hapticframe_jamming import CLASSES, ForceRateJammingClassifier, ForceRateJammingConfig
from hapticframe_jamming import _functional as F
from hapticframe_jamming import plugin as jamming_plugin

RATE_HZ = 100.0


def make(**cfg) -> ForceRateJammingClassifier:
    return ForceRateJammingClassifier(
        ForceRateJammingConfig(**cfg), BuildContext(id="jam", rng=np.random.default_rng(0))
    )


def batch_of(force, t0: float = 0.0, valid=None, channel: str = "force_n") -> SampleBatch:
    force = np.asarray(force, dtype=np.float64)
    t = t0 + np.arange(len(force)) / RATE_HZ
    return SampleBatch(t, {channel: force}, {} if valid is None else {channel: valid})


def approach_signal(rng: np.random.Generator, n: int = 600) -> np.ndarray:
    """A 2-D force: free drag with noise, then a jamming surge and a contact spike."""
    t = np.arange(n) / RATE_HZ
    magnitude = 12.0 + 1.5 * np.sin(2 * np.pi * 0.7 * t)
    surge_start, contact = int(0.6 * n), int(0.9 * n)
    magnitude[surge_start:] += (
        45.0 * ((t[surge_start:] - t[surge_start]) / (t[contact] - t[surge_start])) ** 1.5
    )
    magnitude[contact:] += 150.0 * (t[contact:] - t[contact])
    heading = 0.3
    force = -magnitude[:, None] * np.array([np.cos(heading), np.sin(heading)])
    return force + 0.3 * rng.standard_normal((n, 2))


def stream(clf: ForceRateJammingClassifier, batch: SampleBatch, cuts) -> np.ndarray:
    clf.reset()
    bounds = [0, *sorted(cuts), len(batch)]
    parts = [
        clf.update(batch.select(slice(a, b))).probabilities for a, b in itertools.pairwise(bounds)
    ]
    clf.reset()
    return np.concatenate(parts)


# --- registration and config ----------------------------------------------------------------


def test_registration_spec():
    spec, drag_ratio = jamming_plugin.hapticframe_classifiers()
    assert isinstance(spec, ClassifierSpec) and spec.name == "force-rate-jamming"
    assert drag_ratio.name == "drag-ratio-jamming"
    assert spec.capabilities == {"trainable"}
    assert spec.load_factory() is ForceRateJammingClassifier


def test_registration_module_is_import_light():
    code = (
        "import sys, hapticframe_jamming.plugin, hapticframe_jamming;"
        "heavy = [m for m in ('hapticframe_jamming._classifier',"
        " 'hapticframe_jamming._calibration') if m in sys.modules];"
        "print(heavy); sys.exit(1 if heavy else 0)"
    )
    _assert_exits_cleanly(code)


def test_config_rejects_bad_values():
    with pytest.raises(ValidationError):
        ForceRateJammingConfig(cutoff_hz=60.0, sample_rate_hz=100.0)
    with pytest.raises(ValidationError):
        ForceRateJammingConfig(jamming_rate_n_per_s=float("nan"))
    with pytest.raises(ValidationError):
        ForceRateJammingConfig(unknown_key=1)
    with pytest.raises(ValueError, match="'jam'"):
        make(cutoff_hz=55.0)  # above Nyquist of the default 100 Hz


def test_sample_rate_comes_from_the_input_sensor():
    class FakeSensor:
        def __init__(self) -> None:
            self.channels = {"force_n": ChannelInfo((2,), "N", 250.0)}

    ctx = BuildContext(id="jam", rng=np.random.default_rng(0), inputs={"ft": FakeSensor()})
    assert ForceRateJammingClassifier(ForceRateJammingConfig(), ctx).sample_rate_hz == 250.0
    explicit = ForceRateJammingConfig(sample_rate_hz=50.0)
    assert ForceRateJammingClassifier(explicit, ctx).sample_rate_hz == 50.0
    assert make().sample_rate_hz == 100.0


# --- filtering and rate ---------------------------------------------------------------------


def test_filtered_rate_of_a_ramp_converges_to_its_slope():
    clf = make()
    t = np.arange(300) / RATE_HZ
    force, rate = clf.force_and_rate(batch_of(5.0 + 10.0 * t))
    np.testing.assert_allclose(rate[150:], 10.0, rtol=1e-6)
    # A second-order low-pass lags a ramp by a constant.
    lag = (5.0 + 10.0 * t - force)[150:]
    np.testing.assert_allclose(lag, lag[0], atol=1e-6)
    assert 0.0 < lag[0] < 10.0 * 0.2


def test_filter_starts_at_rest_on_the_first_sample():
    force, rate = make().force_and_rate(batch_of(np.full(50, 37.5)))
    np.testing.assert_allclose(force, 37.5, rtol=1e-12)
    np.testing.assert_allclose(rate, 0.0, atol=1e-9)


def test_vector_and_scalar_channels_give_magnitudes():
    clf = make()
    vec = np.column_stack([np.full(20, 3.0), np.full(20, -4.0)])
    f_vec, _ = clf.force_and_rate(batch_of(vec))
    f_scalar, _ = clf.force_and_rate(batch_of(np.full(20, -5.0)))
    np.testing.assert_allclose(f_vec, 5.0)
    np.testing.assert_allclose(f_scalar, 5.0)


def test_force_magnitude_extremes():
    np.testing.assert_allclose(F.force_magnitude([[3e200, 4e200]]), [F.MAX_FORCE_N])
    np.testing.assert_allclose(F.force_magnitude([[3e-300, 4e-300]]), [5e-300], rtol=1e-12)
    np.testing.assert_array_equal(F.force_magnitude([[0.0, 0.0]]), [0.0])
    assert np.isnan(F.force_magnitude([[np.nan, 1.0], [np.inf, 0.0]])).all()


# --- probabilities --------------------------------------------------------------------------


def test_probabilities_are_valid_and_their_argmax_is_the_threshold_rule():
    rng = np.random.default_rng(7)
    clf = make()
    batch = batch_of(approach_signal(rng))
    probs = clf.predict_proba(batch)
    p = probs.probabilities
    assert probs.classes == CLASSES == ("free", "jamming", "contact")
    assert np.all(np.isfinite(p)) and np.all(p >= 0) and np.all(p <= 1)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-12)
    force, rate = clf.force_and_rate(batch)
    np.testing.assert_array_equal(probs.labels, F.hard_states(force, rate, clf.thresholds))
    # The signal walks through all three states, in order.
    labels = probs.labels
    assert labels[0] == 0 and labels[-1] == 2
    assert np.argmax(labels == 1) < np.argmax(labels == 2)


def test_probabilities_on_a_grid_of_the_force_rate_plane():
    f, r = np.meshgrid(np.linspace(-10, 200, 211), np.linspace(-300, 600, 181))
    thresholds = (6.0, 27.0, 30.0, 70.0)
    p = F.state_probabilities(f.ravel(), r.ravel(), thresholds, 2.0, 5.0)
    np.testing.assert_allclose(p.sum(axis=1), 1.0, atol=1e-12)
    np.testing.assert_array_equal(
        np.argmax(p, axis=1), F.hard_states(f.ravel(), r.ravel(), thresholds)
    )
    # Deep inside each region the probability is near one.
    deep = F.state_probabilities([0.0, 20.0, 150.0], [-50.0, 60.0, 400.0], thresholds, 2.0, 5.0)
    assert np.all(np.diag(deep) > 0.99)


# --- streaming equals batch -------------------------------------------------------------------


@pytest.mark.parametrize("seed", range(6))
def test_streaming_in_any_chunking_equals_batch(seed):
    rng = np.random.default_rng(seed)
    force = approach_signal(rng, n=400)
    force[rng.choice(400, size=12, replace=False)] = np.nan  # held samples
    force[:3] = np.nan  # uninitialised start
    valid = rng.random(400) > 0.03
    batch = batch_of(force, valid=valid)
    clf = make(cutoff_hz=float(rng.uniform(1.0, 8.0)), filter_order=int(rng.integers(1, 5)))
    whole = clf.predict_proba(batch).probabilities
    for _ in range(5):
        cuts = rng.choice(np.arange(1, 400), size=int(rng.integers(1, 40)), replace=False)
        np.testing.assert_allclose(stream(clf, batch, cuts), whole, rtol=0, atol=1e-9)
    # Single-sample updates too, with empty batches in between.
    clf.reset()
    rows = []
    for k in range(len(batch)):
        assert len(clf.update(batch.select(slice(k, k)))) == 0
        rows.append(clf.update(batch.select(slice(k, k + 1))).probabilities)
    np.testing.assert_allclose(np.concatenate(rows), whole, rtol=0, atol=1e-9)


def test_updates_must_move_forward_in_time_until_reset():
    clf = make()
    batch = batch_of(np.full((10, 2), 5.0))
    clf.update(batch)
    with pytest.raises(ValueError, match="increase"):
        clf.update(batch)
    clf.reset()
    clf.update(batch)


def test_movement_end_resets_the_stream():
    clf = make()
    batch = batch_of(np.full((10, 2), 5.0))
    clf.update(batch)
    clf.on_movement_end(None)  # the classifier ignores the result's content
    clf.update(batch)  # same timestamps again: accepted after the reset


# --- extremes --------------------------------------------------------------------------------


def test_empty_batch():
    probs = make().update(SampleBatch.empty({"force_n": ChannelInfo((2,), "N", RATE_HZ)}))
    assert probs.probabilities.shape == (0, 3)


def test_single_sample_is_free():
    probs = make().predict_proba(batch_of([[30.0, 40.0]]))
    assert probs.probabilities.shape == (1, 3)
    assert probs.labels[0] == 0


def test_constant_force_is_free_whatever_its_size():
    for value in (0.0, 1e-12, 15.0, 500.0, 1e6):
        probs = make().predict_proba(batch_of(np.full(200, value)))
        assert np.all(probs.labels == 0), value


def test_huge_force_step_is_contact_and_finite():
    force = np.concatenate([np.full(50, 10.0), np.full(50, 1e6)])
    probs = make().predict_proba(batch_of(force))
    assert np.all(np.isfinite(probs.probabilities))
    assert probs.labels[55] == 2
    assert probs.probabilities[55, 2] == pytest.approx(1.0)
    extreme = make().predict_proba(batch_of(np.concatenate([np.zeros(5), np.full(5, 1e308)])))
    assert np.all(np.isfinite(extreme.probabilities))


def test_tiny_forces_are_free():
    rng = np.random.default_rng(0)
    probs = make().predict_proba(batch_of(1e-9 * rng.standard_normal((100, 2))))
    assert np.all(probs.labels == 0)


def test_nan_samples_hold_the_previous_force():
    rng = np.random.default_rng(1)
    force = approach_signal(rng, n=300)
    holes = np.array([40, 41, 42, 200, 250])
    with_nan = force.copy()
    with_nan[holes, 1] = np.nan
    held = force.copy()
    for k in holes:
        held[k] = held[k - 1]
    clf = make()
    np.testing.assert_allclose(
        clf.predict_proba(batch_of(with_nan)).probabilities,
        clf.predict_proba(batch_of(held)).probabilities,
        rtol=0,
        atol=1e-12,
    )
    # A sample marked invalid is held the same way, whatever value it carries.
    invalid = force.copy()
    invalid[holes] = 1e9
    valid = np.ones(300, dtype=bool)
    valid[holes] = False
    np.testing.assert_allclose(
        clf.predict_proba(batch_of(invalid, valid=valid)).probabilities,
        clf.predict_proba(batch_of(held)).probabilities,
        rtol=0,
        atol=1e-12,
    )


def test_leading_and_all_nan_samples_are_uniform():
    force = np.full((20, 2), np.nan)
    probs = make().predict_proba(batch_of(force)).probabilities
    np.testing.assert_allclose(probs, 1.0 / 3.0)
    force = force.copy()  # SampleBatch froze the first array
    force[5:] = 10.0
    probs = make().predict_proba(batch_of(force)).probabilities
    np.testing.assert_allclose(probs[:5], 1.0 / 3.0)
    assert np.all(np.argmax(probs[5:], axis=1) == 0)


def test_missing_channel_is_a_clear_error():
    with pytest.raises(ValueError, match=r"'force_n'.*force_channel"):
        make().update(batch_of(np.ones((3, 2)), channel="wrench"))
    ok = make(force_channel="wrench").predict_proba(batch_of(np.ones((3, 2)), channel="wrench"))
    assert len(ok) == 3


def test_classifying_a_stream_does_not_import_scipy_signal():
    code = (
        "import sys, numpy as np;"
        "from hapticframe.kinds import BuildContext, SampleBatch;"
        "from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig;"
        "clf = ForceRateJammingClassifier(ForceRateJammingConfig(),"
        " BuildContext(id='j', rng=np.random.default_rng(0)));"
        "[clf.update(SampleBatch(np.array([0.01 * (k + 1)]),"
        " {'force_n': np.array([[3.0 + k, 1.0]])})) for k in range(30)];"
        "sys.exit(1 if 'scipy.signal' in sys.modules else 0)"
    )
    _assert_exits_cleanly(code)


@pytest.mark.parametrize("order", [1, 2, 4])
def test_one_sample_filter_steps_equal_the_array_filter(order):
    """process_one (plain floats) and process (arrays) hand the filter state back and forth
    and give bit-identical force and rate to one pass over everything."""
    from hapticframe_jamming._classifier import ForceRateTracker

    rng = np.random.default_rng(order)
    magnitude = np.abs(approach_signal(rng, n=240)[:, 0])
    t = np.arange(magnitude.size) / RATE_HZ
    sos = butterworth_sos(4.0, RATE_HZ, order)
    whole = ForceRateTracker(sos).process(t, magnitude, np.ones(t.size, dtype=bool))
    mixed = ForceRateTracker(sos)
    assert mixed.process_one(t[0], magnitude[0]) is None  # not initialised yet
    force, rate = np.empty(t.size), np.empty(t.size)
    k = 0
    while k < t.size:
        size = int(rng.integers(1, 6))
        if size == 1 and k > 0:
            force[k], rate[k] = mixed.process_one(float(t[k]), float(magnitude[k]))
            assert mixed.process_one(float(t[k]), 1.0) is None  # time must move on
        else:
            rows = slice(k, k + size)
            force[rows], rate[rows], _ = mixed.process(
                t[rows], magnitude[rows], np.ones(t[rows].size, dtype=bool)
            )
        k += size
    np.testing.assert_array_equal(force, whole[0])
    np.testing.assert_array_equal(rate, whole[1])


def _ramp_with_gap(gap: slice) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A force rising at 10 N/s (free raking as the drag builds), invalid over ``gap``."""
    t = np.arange(200) / RATE_HZ
    magnitude = 5.0 + 10.0 * t
    valid = np.ones(t.size, dtype=bool)
    valid[gap] = False
    return t, magnitude, valid


def test_a_gap_restarts_the_filter_instead_of_reading_a_jump_as_a_rate():
    from hapticframe_jamming._classifier import ForceRateTracker

    sos = butterworth_sos(3.0, RATE_HZ, 2)
    t, magnitude, valid = _ramp_with_gap(slice(80, 110))  # 0.3 s without a valid force
    held_over = ForceRateTracker(sos).process(t, magnitude, valid)[1]
    restarted = ForceRateTracker(sos, restart_after_gap_s=0.05).process(t, magnitude, valid)[1]
    # Held across the gap, the 3 N jump to the next valid force reads as a rate far above
    # the ramp's 10 N/s; restarted at rest on it, the rate starts again from 0.
    assert np.nanmax(held_over[110:140]) > 30.0
    assert restarted[110] == 0.0
    assert np.nanmax(restarted[110:]) < 11.0  # the filter's small overshoot of the ramp
    np.testing.assert_array_equal(restarted[:110], held_over[:110])  # the same until then


def test_a_short_gap_is_held_over_and_a_restart_is_chunking_invariant():
    from hapticframe_jamming._classifier import ForceRateTracker

    sos = butterworth_sos(3.0, RATE_HZ, 2)
    t, magnitude, valid = _ramp_with_gap(slice(80, 83))  # 0.03 s: shorter than the limit
    short = ForceRateTracker(sos, restart_after_gap_s=0.05).process(t, magnitude, valid)
    never = ForceRateTracker(sos).process(t, magnitude, valid)
    np.testing.assert_array_equal(short[1], never[1])
    t, magnitude, valid = _ramp_with_gap(slice(50, 90))
    whole = ForceRateTracker(sos, restart_after_gap_s=0.05).process(t, magnitude, valid)
    stepped = ForceRateTracker(sos, restart_after_gap_s=0.05)
    rates = []
    for k in range(t.size):  # one sample at a time, through process_one where it can
        one = stepped.process_one(float(t[k]), float(magnitude[k])) if valid[k] else None
        if one is None:
            one = tuple(a[0] for a in stepped.process(t[k:k + 1], magnitude[k:k + 1],
                                                      valid[k:k + 1])[:2])
        rates.append(one[1])
    np.testing.assert_allclose(rates, whole[1], rtol=1e-12, atol=1e-12)


def _assert_exits_cleanly(code: str) -> None:
    """Run ``code`` in a fresh interpreter (nothing imported yet) and expect exit status 0."""
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run(
        [sys.executable, "-c", code],
        check=False,
        env={"PYTHONPATH": f"{root / 'plugins'}:{root}"},
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
