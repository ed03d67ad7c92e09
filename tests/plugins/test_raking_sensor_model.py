"""The distance-estimate sensor model: observations where the estimate says, weighted by its
certainty; the failure zone's rule without an estimator; the raking-map suite."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hapticframe import BenchOptions
from hapticframe.kinds import BuildContext, LocatedMeasurement, SampleBatch
from hapticframe_raking import (
    DistanceEstimateConfig,
    DistanceEstimateSensorModel,
    ObjectEstimate,
    RakingEstimator,
    RakingEstimatorConfig,
    load_trials,
    object_point,
    place_observations,
)


def _estimate(d_mm: float, std_mm: float, direction: int = 1, n: int = 1) -> ObjectEstimate:
    return ObjectEstimate(np.full(n, d_mm), np.full(n, std_mm),
                          np.tile(np.eye(3)[direction], (n, 1)), np.full((n, 2), 0.5))


#: One row, the geometry alone: no travel window, no depth, no fingertip point, weight 1.
_GEOMETRY = {"consistency_travel_m": 0.0, "object_depth_m": 0.0, "path_free_weight": 0.0,
             "object_weight": 1.0}


def test_the_object_is_placed_at_the_estimated_distance_and_bearing() -> None:
    config = DistanceEstimateConfig(direction_bearings_deg=(-90.0, 0.0, 90.0), free_points=0,
                                    **_GEOMETRY)
    obs = place_observations(np.array([[1.0, 2.0]]), np.array([np.pi / 2]),
                             _estimate(50.0, 0.0, direction=1), config)
    np.testing.assert_allclose(obs.points_m[obs.weights > 0.5], [[1.0, 2.05]], atol=1e-12)
    left = place_observations(np.array([[1.0, 2.0]]), np.array([0.0]),
                              _estimate(50.0, 0.0, direction=2), config)
    np.testing.assert_allclose(left.points_m, [[1.0, 2.05]], atol=1e-12)


def test_uncertainty_lowers_the_weight_and_far_estimates_place_no_object() -> None:
    config = DistanceEstimateConfig(free_points=2, **_GEOMETRY)
    sure = place_observations(np.zeros((1, 2)), np.zeros(1), _estimate(40.0, 1.0), config)
    unsure = place_observations(np.zeros((1, 2)), np.zeros(1), _estimate(40.0, 5.0), config)
    assert sure.weights[sure.targets == 1].max() > 4 * unsure.weights[unsure.targets == 1].max()
    # Ten times the reference deviation: no object at all (weight 1e-4 < min_weight).
    lost = place_observations(np.zeros((1, 2)), np.zeros(1), _estimate(40.0, 30.0), config)
    assert not (lost.targets == 1).any()
    # The free observations lie between the tool and the estimate less two deviations.
    free = sure.points_m[sure.targets == 0]
    assert len(free) == 2 and np.all((free[:, 0] > 0) & (free[:, 0] < 0.038))
    far = place_observations(np.zeros((1, 2)), np.zeros(1), _estimate(500.0, 1.0), config)
    assert not (far.targets == 1).any()
    nan = place_observations(np.zeros((1, 2)), np.zeros(1), _estimate(np.nan, 1.0), config)
    assert len(nan) == 0


def test_it_reads_the_estimator_and_streams_as_it_batches() -> None:
    trial = load_trials("testing")[0]
    estimator = RakingEstimator(RakingEstimatorConfig(pretrained=True),
                                BuildContext("est", np.random.default_rng(0)))
    t = 0.1 * np.arange(len(trial))
    probs = estimator.update(SampleBatch(t, {"taxel_force": trial.force}))
    model = DistanceEstimateSensorModel(DistanceEstimateConfig(), BuildContext(
        "sm", np.random.default_rng(0), inputs={"est": estimator}))
    located = LocatedMeasurement(t, trial.position_m[:, :2], np.full(len(t), -np.pi / 2),
                                 probs.probabilities, probs.classes)
    whole = model.observe(located)
    model.reset()  # the travel and the window of estimates start again
    rows = [model.observe(located.select(slice(i, i + 1))) for i in range(len(located))]
    streamed = np.concatenate([r.points_m for r in rows])
    np.testing.assert_allclose(streamed, whole.points_m)
    assert model.fallback_rows == 0 and (whole.targets == 1).any()
    # A time the estimator never saw: the failure zone's rule at the fallback distance.
    later = LocatedMeasurement([999.0], [[0.0, 0.0]], [0.0], [[0.0, 1.0]], ("far", "near"))
    fallback = model.observe(later)
    np.testing.assert_allclose(fallback.points_m, [[0.03, 0.0]])
    assert model.fallback_rows == 1


def test_object_point_is_where_the_labels_measure_to() -> None:
    trial = load_trials("testing")[5]
    point = object_point(trial)
    d = np.hypot(*(trial.position_m[:, :2] - point).T) * 1000
    np.testing.assert_allclose(d, trial.distance_mm, atol=0.1)


def test_raking_map_suite_places_and_scores(tmp_path: Path) -> None:
    pytest.importorskip("h5py")
    from hapticframe_bench._raking_map import run_raking_map

    run_raking_map(BenchOptions(tmp_path, echo=lambda _: None))
    report = json.loads((tmp_path / "raking-map.json").read_text())
    assert len(report["per_trial"]) == 20
    ours = report["summary"]["ours"]
    assert ours["trials_placed"] == 20 and ours["error_mm_median"] > 0
    assert 0.005 < report["fixed_distance_m"] < 0.05
    assert 0 <= ours["map_found"] <= 20
    for row in report["per_trial"]:
        error = row["ours_map_error_m"]
        assert error is None or 0 <= error < 0.2
