"""The jamming classifier's fitted thresholds: save, load at build (model_dir), refusals."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, Persistent, SampleBatch, Trainable
from hapticframe_jamming import ForceRateJammingClassifier, ForceRateJammingConfig

RATE_HZ = 100.0
THRESHOLDS = ("jamming_force_n", "jamming_rate_n_per_s", "contact_force_n", "contact_rate_n_per_s")


def make(**cfg) -> ForceRateJammingClassifier:
    return ForceRateJammingClassifier(
        ForceRateJammingConfig(**cfg), BuildContext(id="jam", rng=np.random.default_rng(0))
    )


def labelled_movement(rng: np.random.Generator, approach: bool, t0: float):
    """A 3-D force stream with per-sample labels: free drag, then (when ``approach``) a
    jamming surge (label 1) and a contact spike (label 2)."""
    n = 500
    t = np.arange(n) / RATE_HZ
    magnitude = 8.0 + 1.0 * np.sin(2 * np.pi * rng.uniform(0.4, 0.9) * t)
    labels = np.zeros(n, dtype=np.int64)
    if approach:
        surge, contact = int(rng.integers(250, 320)), int(rng.integers(400, 440))
        magnitude[surge:] += 80.0 * (t[surge:] - t[surge]) ** 1.3
        magnitude[contact:] += 300.0 * (t[contact:] - t[contact])
        labels[surge:] = 1
        labels[contact:] = 2
    direction = np.array([-0.8, 0.1, 0.59]) / np.linalg.norm([-0.8, 0.1, 0.59])
    force = magnitude[:, None] * direction + 0.2 * rng.standard_normal((n, 3))
    return SampleBatch(t0 + t, {"force_n": force}), labels


def training_set(seed: int):
    rng = np.random.default_rng(seed)
    pairs = [labelled_movement(rng, approach=k % 3 != 0, t0=10.0 * k) for k in range(9)]
    return [b for b, _ in pairs], [y for _, y in pairs]


def test_fit_save_and_a_new_classifier_with_model_dir_classifies_identically(tmp_path):
    batches, labels = training_set(0)
    trained = make()
    assert isinstance(trained, Trainable) and isinstance(trained, Persistent)
    trained.fit(batches, labels)
    defaults = ForceRateJammingConfig()
    assert any(getattr(trained.config, k) != getattr(defaults, k) for k in THRESHOLDS)
    trained.save(tmp_path)
    assert [p.name for p in tmp_path.iterdir()] == ["thresholds.json"]
    loaded = make(model_dir=str(tmp_path))
    assert loaded.thresholds == trained.thresholds
    assert loaded.training_report() == trained.training_report() != {}
    test_batches, _ = training_set(1)
    for batch in test_batches:
        np.testing.assert_array_equal(
            loaded.predict_proba(batch).probabilities, trained.predict_proba(batch).probabilities
        )
    # And differently from an untrained classifier (the test can tell the two apart).
    untrained = make()
    assert any(
        not np.array_equal(untrained.predict(b), loaded.predict(b)) for b in test_batches
    )


def test_the_artifact_is_plain_json_with_the_filter(tmp_path):
    classifier = make(jamming_force_n=7.5, cutoff_hz=4.0)
    path = classifier.save(tmp_path)
    record = json.loads(path.read_text())
    assert record["format"] == "hapticframe-force-rate-jamming"
    assert record["thresholds"]["jamming_force_n"] == 7.5
    assert record["filter"] == {"cutoff_hz": 4.0, "filter_order": 2, "sample_rate_hz": 100.0}


def test_load_refuses_another_filter_or_format(tmp_path):
    make(jamming_force_n=7.5).save(tmp_path)
    with pytest.raises(ValueError, match="cutoff_hz"):
        make(model_dir=str(tmp_path), cutoff_hz=5.0)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        make(model_dir=str(tmp_path), sample_rate_hz=200.0)
    assert make(model_dir=str(tmp_path)).config.jamming_force_n == 7.5
    record = json.loads((tmp_path / "thresholds.json").read_text())
    (tmp_path / "thresholds.json").write_text(json.dumps({**record, "format_version": 99}))
    with pytest.raises(ValueError, match="is not a hapticframe-force-rate-jamming"):
        make(model_dir=str(tmp_path))
    del record["thresholds"]["contact_force_n"]
    (tmp_path / "thresholds.json").write_text(json.dumps(record))
    with pytest.raises(ValueError, match="bad thresholds"):
        make(model_dir=str(tmp_path))
    with pytest.raises(ValueError, match="no jamming thresholds"):
        make(model_dir=str(tmp_path / "missing"))


def test_refitting_a_loaded_classifier_starts_from_the_data(tmp_path):
    batches, labels = training_set(0)
    make(jamming_force_n=100.0, jamming_rate_n_per_s=500.0).save(tmp_path)
    loaded = make(model_dir=str(tmp_path))
    loaded.fit(batches, labels)
    fresh = make()
    fresh.fit(batches, labels)
    assert loaded.thresholds == fresh.thresholds
