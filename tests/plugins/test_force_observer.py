"""The force-observer feature extractor: filtering, Eq. 3.10, validity, fit, save/load, kit."""

from __future__ import annotations

import itertools
import json
import warnings

import numpy as np
import pytest
from pydantic import ValidationError

import hapticframe.kinds
from hapticframe import FeatureExtractorSpec
from hapticframe.geometry import rotation_matrix_from_wxyz
from hapticframe.kinds import (
    BuildContext,
    ChannelInfo,
    Component,
    Persistent,
    SampleBatch,
    Trainable,
    concatenate_batches,
)
from hapticframe.testing import run_checks
from hapticframe_force_observer import (
    ExcitationWarning,
    ForceObserver,
    ForceObserverConfig,
)
from hapticframe_force_observer import plugin as observer_plugin
from hapticframe_force_observer._functional import rotation_angle_rad

RATE_HZ = 100.0
G = 9.80665
MASS_KG = 0.8
Q_TRUE = np.array([0.97, 0.12, -0.18, 0.10]) / np.linalg.norm([0.97, 0.12, -0.18, 0.10])
R_TRUE = rotation_matrix_from_wxyz(Q_TRUE)
BIAS_N = np.array([1.5, -0.7, 2.0])
FORCE, ACCEL = "force_n", "acceleration_m_per_s2"


def make(context_inputs=None, **cfg) -> ForceObserver:
    return ForceObserver(
        ForceObserverConfig(**cfg),
        BuildContext(id="observer", rng=np.random.default_rng(0), inputs=context_inputs or {}),
    )


def recording(rng: np.random.Generator, n: int = 800, t0: float = 0.0, noise_n: float = 0.2,
              mass: float = MASS_KG, rotation: np.ndarray = R_TRUE,
              bias: np.ndarray = BIAS_N) -> SampleBatch:
    """Free motion in air: the tool tumbles slowly about a random axis and shakes.

    The IMU reads the specific force R_wiᵀ (a_w + g ẑ); the sensor reads m R a + ε + noise.
    """
    t = t0 + np.arange(1, n + 1) / RATE_HZ
    axis = rng.standard_normal(3)
    axis /= np.linalg.norm(axis)
    angle = 1.2 * np.sin(2 * np.pi * 0.15 * (t - t0)) + rng.uniform(0, np.pi)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    shake = 1.5 * np.sin(2 * np.pi * np.outer(t, [0.7, 1.1, 0.9]) + rng.uniform(0, 6, 3))
    accel = np.empty((n, 3))
    for i, theta in enumerate(angle):
        r_wi = np.eye(3) + np.sin(theta) * k + (1 - np.cos(theta)) * (k @ k)
        accel[i] = r_wi.T @ (shake[i] + [0.0, 0.0, G])
    force = mass * accel @ rotation.T + bias + rng.normal(0.0, noise_n, (n, 3))
    return SampleBatch(t, {FORCE: force, ACCEL: accel})


def stream(observer: ForceObserver, batch: SampleBatch, cuts) -> SampleBatch:
    observer.reset()
    bounds = [0, *sorted(cuts), len(batch)]
    parts = [observer.update(batch.select(slice(a, b))) for a, b in itertools.pairwise(bounds)]
    observer.reset()
    return concatenate_batches([p for p in parts if len(p)])


def inline(**extra):
    return dict(mass_kg=MASS_KG, imu_rotation_wxyz=tuple(Q_TRUE), bias_n=tuple(BIAS_N), **extra)


# --- registration and config ----------------------------------------------------------------


def test_registration_spec():
    (spec,) = observer_plugin.hapticframe_feature_extractors()
    assert isinstance(spec, FeatureExtractorSpec) and spec.name == "force-observer"
    assert spec.load_factory() is ForceObserver
    assert set(spec.consumes) == {FORCE, ACCEL}


def test_kit_checks_pass():
    (spec,) = observer_plugin.hapticframe_feature_extractors()
    results = run_checks(spec)
    failed = [r for r in results if r.status != "PASS"]
    assert not failed, failed
    assert len(results) >= 8


def test_config_rejects_bad_values():
    with pytest.raises(ValidationError, match="model_dir provides"):
        ForceObserverConfig(model_dir="x", mass_kg=1.0)
    with pytest.raises(ValidationError, match="unit quaternion"):
        ForceObserverConfig(imu_rotation_wxyz=(1.0, 1.0, 0.0, 0.0))
    with pytest.raises(ValidationError, match="Nyquist"):
        ForceObserverConfig(sample_rate_hz=20.0, cutoff_hz=10.0)
    with pytest.raises(ValidationError):
        ForceObserverConfig(max_age_s=0.0)


def test_input_alignment_is_hold_with_the_configured_age():
    alignment_type = getattr(hapticframe.kinds, "InputAlignment", None)
    if alignment_type is None:
        pytest.skip("hapticframe.kinds.InputAlignment is not in this tree yet")
    alignment = make(max_age_s=0.04).input_alignment
    assert isinstance(alignment, alignment_type)
    assert alignment.method == "hold" and alignment.max_age_s == 0.04


class _FakeSensor(Component):
    kind = hapticframe.kinds.Sensor.kind

    def __init__(self, rate_hz: float) -> None:
        super().__init__(None, BuildContext(id="ft", rng=np.random.default_rng(0)))
        self.channels = {FORCE: ChannelInfo((3,), "N", rate_hz)}


def test_sample_rate_comes_from_the_force_input():
    observer = make({"ft": _FakeSensor(50.0)}, cutoff_hz=5.0)
    assert observer.sample_rate_hz == 50.0
    assert observer.output_channels[FORCE] == ChannelInfo((3,), "N", 50.0)
    with pytest.raises(ValueError, match="Nyquist"):
        make({"ft": _FakeSensor(15.0)}, cutoff_hz=10.0)
    assert make().sample_rate_hz == RATE_HZ


# --- Eq. 3.10 on filtered inputs ------------------------------------------------------------


def test_defaults_pass_the_filtered_force_through():
    rng = np.random.default_rng(1)
    batch = recording(rng, n=300)
    out = make().transform(batch)
    observer = make(mass_kg=0.0)  # the same thing said explicitly
    np.testing.assert_array_equal(out.channels[FORCE], observer.transform(batch).channels[FORCE])
    # Low-pass filtered: close to the raw force, far smoother.
    raw = batch.channels[FORCE]
    assert np.max(np.abs(out.channels[FORCE] - raw)) < 2.0
    assert np.std(np.diff(out.channels[FORCE], axis=0)) < 0.5 * np.std(np.diff(raw, axis=0))


def test_constant_inputs_give_eq_3_10_exactly():
    """The filter starts at rest on the first sample: a constant input passes unchanged."""
    n = 50
    a = np.array([0.3, -1.0, 9.7])
    f = np.array([4.0, 2.0, 11.0])
    batch = SampleBatch(
        np.arange(n) / RATE_HZ, {FORCE: np.tile(f, (n, 1)), ACCEL: np.tile(a, (n, 1))}
    )
    out = make(**inline()).transform(batch)
    expected = f - MASS_KG * R_TRUE @ a - BIAS_N
    np.testing.assert_allclose(out.channels[FORCE], np.tile(expected, (n, 1)), atol=1e-9)
    assert out.valid[FORCE].all()


def test_removes_the_inertial_load_of_a_free_motion():
    rng = np.random.default_rng(2)
    batch = recording(rng, noise_n=0.2)
    out = make(**inline()).transform(batch)
    raw_rms = np.sqrt(np.mean(np.sum(batch.channels[FORCE] ** 2, axis=1)))
    rms = np.sqrt(np.mean(np.sum(out.channels[FORCE] ** 2, axis=1)))
    assert raw_rms > 5.0 and rms < 0.2  # the noise, further reduced by the low-pass filter


def test_streaming_equals_batch_in_any_chunking_with_invalid_rows():
    rng = np.random.default_rng(3)
    batch = recording(rng, n=400)
    force, accel = batch.channels[FORCE].copy(), batch.channels[ACCEL].copy()
    force[[0, 1, 57, 200]] = np.nan
    accel[[5, 120, 121]] = np.inf
    accel_valid = np.ones(400, dtype=bool)
    accel_valid[300:320] = False  # stale IMU samples
    batch = SampleBatch(batch.timestamps_s, {FORCE: force, ACCEL: accel}, {ACCEL: accel_valid})
    observer = make(**inline())
    whole = observer.transform(batch)
    for seed in range(4):
        cuts = np.random.default_rng(seed).choice(np.arange(1, 400), size=seed * 15 + 1,
                                                  replace=False)
        streamed = stream(observer, batch, cuts)
        np.testing.assert_allclose(streamed.channels[FORCE], whole.channels[FORCE],
                                   rtol=1e-12, atol=1e-12)
        np.testing.assert_array_equal(streamed.valid[FORCE], whole.valid[FORCE])
    one_at_a_time = stream(observer, batch, range(1, 400))
    np.testing.assert_allclose(one_at_a_time.channels[FORCE], whole.channels[FORCE], atol=1e-12)


def test_invalid_samples_are_flagged_and_do_not_poison_the_filter():
    rng = np.random.default_rng(4)
    batch = recording(rng, n=200)
    force = batch.channels[FORCE].copy()
    bad = [0, 40, 41, 90]
    corrupted = force.copy()
    corrupted[bad[:2]] = np.nan
    corrupted[bad[2:]] = 1e6  # garbage the sensor flagged invalid
    valid = np.ones(200, dtype=bool)
    valid[bad] = False
    observer = make(**inline())
    out = observer.transform(SampleBatch(batch.timestamps_s, {FORCE: corrupted,
                                                              ACCEL: batch.channels[ACCEL]},
                                         {FORCE: valid}))
    assert out.channels[FORCE].dtype == np.float64
    assert np.all(np.isfinite(out.channels[FORCE]))
    np.testing.assert_array_equal(out.valid[FORCE], valid)
    # Identical to a stream whose bad samples were the last valid ones (sample-and-hold);
    # before the first valid sample there is nothing to hold: the sample starts the filter.
    held = force.copy()
    held[0] = force[1]
    held[40] = held[41] = force[39]
    held[90] = force[89]
    reference = observer.transform(SampleBatch(batch.timestamps_s, {FORCE: held,
                                                                    ACCEL: batch.channels[ACCEL]}))
    np.testing.assert_allclose(out.channels[FORCE][1:], reference.channels[FORCE][1:],
                               atol=1e-9)
    assert np.all(np.abs(out.channels[FORCE]) < 50.0)  # the 1e6 never leaked in


def test_missing_channel_is_a_clear_error():
    batch = SampleBatch(np.arange(3.0), {FORCE: np.zeros((3, 3))})
    with pytest.raises(ValueError, match="acceleration_m_per_s2"):
        make().update(batch)


# --- fit, report, save and load -------------------------------------------------------------


def fitted(rng: np.random.Generator, **recording_kwargs) -> ForceObserver:
    batches = [recording(rng, t0=10.0 * k, **recording_kwargs) for k in range(4)]
    observer = make()
    with warnings.catch_warnings():
        warnings.simplefilter("error", ExcitationWarning)
        observer.fit(batches)
    return observer


def test_fit_recovers_parameters_and_reports():
    observer = fitted(np.random.default_rng(5))
    assert isinstance(observer, Trainable) and isinstance(observer, Persistent)
    p = observer.parameters
    assert p.mass_kg == pytest.approx(MASS_KG, abs=0.01)
    assert np.degrees(rotation_angle_rad(p.rotation.T @ R_TRUE)) < 0.5
    np.testing.assert_allclose(p.bias_n, BIAS_N, atol=0.05)
    report = json.loads(json.dumps(observer.training_report(), allow_nan=False))
    assert report["recordings"] == 4 and report["samples"] == 3200
    assert report["mass_kg"] == pytest.approx(p.mass_kg)
    assert report["residual_rms_before_n"] > 5.0 > 0.3 > report["residual_rms_n"]
    assert report["excited_directions"] == 3 and report["condition"] >= 1.0
    np.testing.assert_allclose(report["rotation"], p.rotation)


def test_fit_on_one_axis_motion_warns():
    rng = np.random.default_rng(6)
    n = 500
    t = np.arange(1, n + 1) / RATE_HZ
    accel = np.zeros((n, 3))
    accel[:, 0] = 2.0 * np.sin(2 * np.pi * 0.8 * t)
    accel[:, 2] = G
    force = MASS_KG * accel @ R_TRUE.T + BIAS_N + rng.normal(0, 0.2, (n, 3))
    observer = make()
    with pytest.warns(ExcitationWarning, match="not identifiable"):
        observer.fit([SampleBatch(t, {FORCE: force, ACCEL: accel})])
    assert "not identifiable" in observer.training_report()["warning"]
    assert rotation_angle_rad(observer.parameters.rotation) <= rotation_angle_rad(R_TRUE) + 0.01


def test_save_load_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    observer = fitted(rng)
    observer.save(tmp_path)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["model.json", "model.npz"]
    loaded = make(model_dir=str(tmp_path))
    assert loaded.parameters.mass_kg == observer.parameters.mass_kg
    np.testing.assert_array_equal(loaded.parameters.rotation, observer.parameters.rotation)
    np.testing.assert_array_equal(loaded.parameters.bias_n, observer.parameters.bias_n)
    assert loaded.training_report() == observer.training_report()
    batch = recording(rng, n=200)
    np.testing.assert_array_equal(loaded.transform(batch).channels[FORCE],
                                  observer.transform(batch).channels[FORCE])
    # Inline parameters give the same numbers as the artifact (to quaternion rounding).
    p = observer.parameters
    inline_observer = make(mass_kg=p.mass_kg, imu_rotation_wxyz=tuple(p.rotation_wxyz),
                           bias_n=tuple(p.bias_n))
    np.testing.assert_allclose(inline_observer.transform(batch).channels[FORCE],
                               observer.transform(batch).channels[FORCE], atol=1e-9)


def test_load_refuses_what_does_not_fit(tmp_path):
    observer = make(**inline())
    with pytest.raises(ValueError, match="no force-observer model"):
        make(model_dir=str(tmp_path))
    observer.save(tmp_path)
    meta = json.loads((tmp_path / "model.json").read_text())
    (tmp_path / "model.json").write_text(json.dumps({**meta, "format": "other"}))
    with pytest.raises(ValueError, match="is not a hapticframe-force-observer"):
        make(model_dir=str(tmp_path))
    (tmp_path / "model.json").write_text(json.dumps(meta))
    np.savez(tmp_path / "model.npz", rotation=np.diag([1.0, 1.0, -1.0]), bias_n=np.zeros(3))
    with pytest.raises(ValueError, match="not a rotation"):
        make(model_dir=str(tmp_path))
    np.savez(tmp_path / "model.npz", rotation=np.eye(3), bias_n=np.zeros(2))
    with pytest.raises(ValueError, match="bias_n"):
        make(model_dir=str(tmp_path))
    np.savez(tmp_path / "model.npz", rotation=np.eye(3))
    with pytest.raises(ValueError, match="no force-observer model"):
        make(model_dir=str(tmp_path))
