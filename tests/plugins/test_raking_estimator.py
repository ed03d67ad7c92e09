"""The raking-estimator classifier: streaming equals batch, trials restart its window, bad
input is handled, training saves and loads, and the scoring counts what it should."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hapticframe.kinds import BuildContext, SampleBatch
from hapticframe_raking import (
    EstimatorSettings,
    ObjectEstimate,
    RakingEstimator,
    RakingEstimatorConfig,
    RakingModel,
    TrainingTrial,
    fit_model,
    load_trials,
    score_trials,
    select_inputs,
)


def _estimator(**config: object) -> RakingEstimator:
    return RakingEstimator(RakingEstimatorConfig(**config),  # type: ignore[arg-type]
                           BuildContext("est", np.random.default_rng(0)))


def _batch(trial_force: np.ndarray, t0: float = 0.0) -> SampleBatch:
    t = t0 + 0.1 * np.arange(len(trial_force))
    return SampleBatch(t, {"taxel_force": trial_force})


def test_streaming_in_chunks_equals_the_whole_trial() -> None:
    trial = load_trials("testing")[0]
    est = _estimator(pretrained=True)
    whole = est.predict_proba(_batch(trial.force))
    model = est.model
    direct = model.estimate_trial(select_inputs(trial.force, "4_3-axis"))
    est.reset()
    parts, start = [], 0
    for size in (1, 3, 7, 1, 20, 100):
        parts.append(est.update(_batch(trial.force[start:start + size], 0.1 * start)))
        start += size
    streamed = np.concatenate([p.probabilities for p in parts])
    np.testing.assert_allclose(streamed, whole.probabilities, atol=1e-12)
    _, estimates = est.estimates
    np.testing.assert_allclose(estimates.distance_mm, direct.distance_mm, atol=1e-9)
    assert np.all(estimates.distance_std_mm > 0)
    np.testing.assert_allclose(estimates.direction_proba.sum(axis=1), 1.0)


def test_a_pause_starts_a_new_window() -> None:
    a, b = load_trials("testing")[:2]
    est = _estimator(pretrained=True)
    est.update(_batch(a.force))
    est.update(_batch(b.force, t0=100.0))
    _, joined = est.estimates
    alone = est.model.estimate_trial(select_inputs(b.force, "4_3-axis"))
    np.testing.assert_allclose(joined.distance_mm[len(a):], alone.distance_mm, atol=1e-9)


def test_nan_samples_are_held_and_counted() -> None:
    force = load_trials("testing")[0].force[:30].copy()
    force[10] = np.nan
    est = _estimator(pretrained=True)
    probs = est.update(_batch(force))
    assert np.all(np.isfinite(probs.probabilities)) and est.replaced_samples == 1
    held = force.copy()
    held[10] = held[9]
    est2 = _estimator(pretrained=True)
    np.testing.assert_allclose(est2.update(_batch(held)).probabilities, probs.probabilities)


def test_near_probability_is_a_laplace_cdf() -> None:
    est = ObjectEstimate(np.array([10.0, 30.0, 50.0]), np.full(3, np.sqrt(2.0) * 5.0),
                         np.full((3, 3), 1 / 3), np.full((3, 2), 0.5))
    p = est.near_probability(30.0)
    np.testing.assert_allclose(p, [1 - 0.5 * np.exp(-4), 0.5, 0.5 * np.exp(-4)])


def test_untrained_or_wrong_input_is_a_clear_error() -> None:
    est = _estimator()
    with pytest.raises(RuntimeError, match="not trained"):
        est.update(_batch(np.zeros((3, 4, 3))))
    trained = _estimator(pretrained=True)
    with pytest.raises(ValueError, match=r"per-sample shape \(4, 2\)"):
        trained.update(SampleBatch(np.arange(3.0), {"taxel_force": np.zeros((3, 4, 2))}))
    with pytest.raises(ValueError, match="no label channel 'distance_mm'"):
        trained.fit([_batch(np.zeros((30, 4, 3)))], [np.zeros(30)])


def test_fit_save_load_round_trip(tmp_path: Path) -> None:
    pytest.importorskip("torch")
    trials = load_trials("training")[:6]
    batches = [SampleBatch(0.1 * np.arange(len(t)), {
        "taxel_force": t.force, "distance_mm": t.distance_mm,
        "direction_class": t.direction.astype(float), "depth_class": t.depth.astype(float)})
        for t in trials]
    est = _estimator(input_set="1_3-axis", epochs=2, hidden_units=8, window_steps=5)
    est.fit(batches, [t.direction for t in trials])
    report = est.training_report()
    assert report["windows"] == sum(len(t) - 20 for t in trials) and len(report["losses"]) == 2
    est.save(tmp_path)
    again = _estimator(input_set="1_3-axis", epochs=2, hidden_units=8, window_steps=5,
                       model_dir=str(tmp_path))
    x = batches[0]
    np.testing.assert_array_equal(est.predict_proba(x).probabilities,
                                  again.predict_proba(x).probabilities)
    with pytest.raises(ValueError, match="reads 1_3-axis over 5 steps"):
        _estimator(input_set="4_3-axis", model_dir=str(tmp_path))


def test_training_is_seeded() -> None:
    pytest.importorskip("torch")
    trials = [TrainingTrial(select_inputs(t.force, "1_norm"), t.distance_mm, t.direction,
                            t.depth) for t in load_trials("training")[:3]]
    settings = EstimatorSettings(input_set="1_norm", epochs=1, hidden_units=4, window_steps=3)
    a, _ = fit_model(trials, settings, np.random.default_rng(5))
    b, _ = fit_model(trials, settings, np.random.default_rng(5))
    c, _ = fit_model(trials, settings, np.random.default_rng(6))
    np.testing.assert_array_equal(a.lstm.kernel, b.lstm.kernel)
    assert not np.array_equal(a.lstm.kernel, c.lstm.kernel)
    with pytest.raises(ValueError, match="no training trials"):
        fit_model([], settings, np.random.default_rng(0))
    bad = [TrainingTrial(np.full((30, 1), np.nan), np.ones(30), np.zeros(30, np.int64),
                         np.zeros(30, np.int64))]
    with pytest.raises(ValueError, match="NaN or infinity"):
        fit_model(bad, settings, np.random.default_rng(0))


def test_the_shipped_model_loads_and_describes_itself() -> None:
    est = _estimator(pretrained=True)
    assert isinstance(est.model, RakingModel)
    assert est.model.settings.input_set == "4_3-axis"
    with pytest.raises(ValueError, match="either 'model_dir' or 'pretrained"):
        RakingEstimatorConfig(pretrained=True, model_dir="x")


def test_score_trials_counts_a_perfect_and_a_wrong_estimate() -> None:
    trials = load_trials("testing")[:2]

    def perfect_for(trial_index: int):  # type: ignore[no-untyped-def]
        calls = iter(trials)

        def estimate(inputs: np.ndarray) -> ObjectEstimate:
            trial = next(calls)
            n = len(trial)
            direction = np.eye(3)[trial.direction]
            depth = np.eye(2)[(trial.depth + trial_index) % 2]
            return ObjectEstimate(trial.distance_mm + 3.0, np.ones(n), direction, depth)
        return estimate

    scores = score_trials(perfect_for(0), trials, "4_norm")
    np.testing.assert_allclose(scores.direction_accuracy, 1.0)
    np.testing.assert_allclose(scores.distance_mae_mm, 3.0)
    np.testing.assert_allclose(scores.final_distance_error_mm, 3.0)
    wrong = score_trials(perfect_for(1), trials, "4_norm")
    np.testing.assert_allclose(wrong.depth_accuracy, 0.0)
    np.testing.assert_allclose(wrong.final_depth_correct, 0.0)


@pytest.mark.slow
def test_the_shipped_model_is_what_the_training_example_trains(tmp_path: Path,
                                                              monkeypatch: pytest.MonkeyPatch
                                                              ) -> None:
    pytest.importorskip("torch")
    from hapticframe.cli._cli import main
    from hapticframe_raking import pretrained_model_dir

    root = Path(__file__).resolve().parents[2]
    monkeypatch.chdir(root)  # the example's paths are relative to the repository's root
    assert main(["train", "examples/raking-train.yaml", "--out", str(tmp_path / "t")]) == 0
    fresh = RakingModel.load(tmp_path / "t" / "estimator")
    shipped = RakingModel.load(pretrained_model_dir())
    assert fresh.settings == shipped.settings
    # Same seed, one thread, float64: the same model up to the CPU's rounding, which a
    # different machine may let drift over the epochs; the estimates must still agree.
    x = select_inputs(load_trials("testing")[0].force, "4_3-axis")
    a, b = fresh.estimate_trial(x), shipped.estimate_trial(x)
    assert np.median(np.abs(a.distance_mm - b.distance_mm)) < 5.0
    assert np.mean(a.direction_proba.argmax(1) == b.direction_proba.argmax(1)) > 0.9


def test_the_distance_cap_bounds_the_training_targets() -> None:
    from hapticframe_raking._model import _training_arrays

    trials = [TrainingTrial(select_inputs(t.force, "1_norm"), t.distance_mm, t.direction,
                            t.depth) for t in load_trials("training")[:2]]
    capped = _training_arrays(trials, EstimatorSettings(input_set="1_norm", range_mm=100.0))[1]
    free = _training_arrays(trials, EstimatorSettings(input_set="1_norm"))[1]
    assert free.max() > 140.0 and capped.max() == 100.0
    np.testing.assert_array_equal(capped, np.minimum(free, 100.0))
    for bad in (0.0, -5.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="range_mm"):
            EstimatorSettings(range_mm=bad)
    with pytest.raises(ValueError):
        RakingEstimatorConfig(range_mm=float("nan"))


def test_cross_validation_holds_out_whole_configurations() -> None:
    pytest.importorskip("torch")
    from hapticframe_raking import cross_validate, selected_settings, trial_groups

    trials = load_trials("training")
    groups = trial_groups(trials)
    assert len(np.unique(groups)) == 16 and np.all(np.bincount(groups)[1:] == 5)
    few = [t for t in trials if t.name[:2] in ("01", "02", "03")]
    rows = cross_validate(few, EstimatorSettings(input_set="1_norm", epochs=1, hidden_units=4),
                          grid={"range_mm": (None, 100.0)}, folds=3)
    assert [r["settings"] for r in rows] == [{"range_mm": None}, {"range_mm": 100.0}]
    for r in rows:
        assert np.isfinite(r["distance_mae_in_range_mm"]) and r["distance_mae_mm"] > 0
        # Against the truth capped at the range: never more than against the true distance
        # for a model whose estimates stay within it.
        assert np.isfinite(r["distance_mae_capped_mm"]) and r["distance_mae_capped_mm"] > 0
        assert 0.0 <= r["direction_accuracy"] <= 1.0
    with pytest.raises(ValueError, match="cannot make 4 folds"):
        cross_validate(few, EstimatorSettings(input_set="1_norm"), folds=4)
    assert selected_settings("4_3-axis").range_mm == 100.0
