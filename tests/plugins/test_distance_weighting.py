"""Where the distance estimate is informative: the weighting of the ``distance-estimate``
sensor model (sharp certainty of the predicted deviation, consistency of the implied
object points over travel, reports by travel spacing, free evidence)."""

from __future__ import annotations

import numpy as np
import pydantic
import pytest

from hapticframe.kinds import BuildContext, LocatedMeasurement, MovementResult
from hapticframe_raking import (
    DistanceEstimateConfig,
    DistanceEstimateSensorModel,
    ObjectEstimate,
    certainty_weights,
    consistency_weights,
    place_observations,
)


def _approach(distances_mm: np.ndarray, std_mm: float, step_m: float = 0.001
              ) -> tuple[np.ndarray, np.ndarray, ObjectEstimate]:
    """A straight movement along +x, one row per ``step_m``, with the given estimates."""
    n = len(distances_mm)
    positions = np.column_stack([step_m * np.arange(n), np.zeros(n)])
    est = ObjectEstimate(np.asarray(distances_mm, dtype=np.float64), np.full(n, std_mm),
                         np.tile([0.0, 1.0, 0.0], (n, 1)), np.full((n, 2), 0.5))
    return positions, np.zeros(n), est


def test_certainty_halves_at_the_reference_and_falls_sharply() -> None:
    config = DistanceEstimateConfig(reference_std_m=0.003, certainty_exponent=4.0)
    w = certainty_weights(np.array([0.0, 0.003, 0.006, 0.03, np.nan, -1.0]), config)
    np.testing.assert_allclose(w[:4], [1.0, 0.5, 1.0 / 17.0, 1.0 / 10001.0])
    assert w[4] == 0.0 and w[5] == 0.0
    # The exponent 2 is the old Gaussian-product weight s² / (s² + σ²).
    soft = certainty_weights(np.array([0.006]), config.model_copy(
        update={"certainty_exponent": 2.0}))
    np.testing.assert_allclose(soft, [0.2])
    with pytest.raises(ValueError, match="one-dimensional"):
        certainty_weights(np.zeros((2, 2)), config)


def test_consistency_weights_refuse_nan_and_bad_shapes() -> None:
    config = DistanceEstimateConfig(consistency_std_m=0.003)
    np.testing.assert_allclose(consistency_weights(np.array([0.0, 0.003, np.nan]), config),
                               [1.0, 0.5, 0.0])
    with pytest.raises(ValueError, match="one-dimensional"):
        consistency_weights(np.zeros((3, 1)), config)


def test_a_certain_estimate_that_follows_the_travel_places_the_object() -> None:
    # The object's outline at x = 0.1 m: the estimate shrinks as the tool moves on.
    x = 0.001 * np.arange(60)
    positions, headings, est = _approach(1000 * (0.1 - x), std_mm=1.0)
    config = DistanceEstimateConfig(report_spacing_m=0.005, object_depth_m=0.0)
    obs = place_observations(positions, headings, est, config)
    objects = obs.points_m[obs.targets == 1]
    assert len(objects) > 0
    np.testing.assert_allclose(objects[:, 0], 0.1, atol=1e-9)
    # Full weight: object_weight x P(ahead) x certainty (0.92 at 1 mm) x consistency (1).
    assert obs.weights[obs.targets == 1].max() == pytest.approx(
        config.object_weight / (1 + (1 / 3) ** 4), rel=1e-6)


def test_an_estimate_that_does_not_follow_the_travel_places_no_object() -> None:
    # The same 20 mm whatever the travel (what a flat drag force gives): certain, but the
    # implied object moves with the tool, so there is no object, only free sand ahead.
    positions, headings, est = _approach(np.full(60, 20.0), std_mm=1.0)
    config = DistanceEstimateConfig(object_depth_m=0.0)
    obs = place_observations(positions, headings, est, config)
    off = place_observations(positions, headings, est,
                             config.model_copy(update={"consistency_travel_m": 0.0}))
    full = off.weights[off.targets == 1].max()
    # Repeated over 2 cm the implied points spread by 5.8 mm: weight 1 / (1 + 1.93⁴).
    assert obs.weights[obs.targets == 1].max() < 0.1 * full
    # Before the movement has travelled one window, no object at all.
    first = place_observations(positions[:15], headings[:15], _approach(
        np.full(15, 20.0), 1.0)[2], config)
    assert not (first.targets == 1).any()
    # ... and free sand just ahead instead, weighted by how little the estimate follows.
    ahead = obs.points_m[(obs.targets == 0) & (obs.weights > 0.4)]
    assert len(ahead) > 0 and np.all(ahead[:, 0] <= positions[-1, 0]
                                     + config.untracked_free_m + 1e-12)


def test_far_with_confidence_gives_free_evidence_and_no_object() -> None:
    # 0.3 m away, 1 mm deviation, following the travel: free up to max_range_m, no object.
    x = 0.001 * np.arange(60)
    positions, headings, est = _approach(1000 * (0.3 - x), std_mm=1.0)
    config = DistanceEstimateConfig(path_free_weight=0.0, untracked_free_weight=0.0)
    obs = place_observations(positions, headings, est, config)
    assert not (obs.targets == 1).any()
    assert len(obs) > 0 and np.all(obs.targets == 0)
    reach = obs.points_m[:, 0] - positions[-1, 0]
    assert reach.max() > 0.05 and reach.max() <= config.max_range_m
    assert obs.weights.max() > 0.9


def test_an_uncertain_estimate_gives_no_weight() -> None:
    x = 0.001 * np.arange(60)
    positions, headings, est = _approach(1000 * (0.05 - x), std_mm=30.0)
    config = DistanceEstimateConfig(path_free_weight=0.0, untracked_free_weight=0.0)
    obs = place_observations(positions, headings, est, config)
    assert len(obs) == 0
    sure = place_observations(positions, headings, _approach(1000 * (0.05 - x), 1.0)[2],
                              config)
    assert (sure.targets == 1).any()


def test_nan_rows_place_nothing_and_mismatched_rows_are_refused() -> None:
    x = 0.001 * np.arange(40)
    positions, headings, est = _approach(1000 * (0.1 - x), std_mm=1.0)
    est.distance_mm[:] = np.nan
    assert len(place_observations(positions, headings, est,
                                  DistanceEstimateConfig())) == 0
    positions[:] = np.nan
    assert len(place_observations(positions, headings, _approach(np.full(40, 20.0), 1.0)[2],
                                  DistanceEstimateConfig())) == 0
    with pytest.raises(ValueError, match="row for row"):
        place_observations(np.zeros((3, 2)), np.zeros(2), _approach(np.zeros(3), 1.0)[2],
                           DistanceEstimateConfig())
    empty = place_observations(np.zeros((0, 2)), np.zeros(0), _approach(np.zeros(0), 1.0)[2],
                               DistanceEstimateConfig())
    assert len(empty) == 0


@pytest.mark.parametrize("field, value", [("report_spacing_m", -0.01),
                                          ("consistency_std_m", 0.0),
                                          ("object_weight", float("nan")),
                                          ("path_free_weight", 2.0),
                                          ("certainty_exponent", 0.5)])
def test_bad_config_values_are_refused(field: str, value: float) -> None:
    with pytest.raises(pydantic.ValidationError, match=field):
        DistanceEstimateConfig(**{field: value})


class _Fixed:
    """An estimator stand-in: the estimates of one approach, by time."""

    def __init__(self, times: np.ndarray, est: ObjectEstimate) -> None:
        self.times, self.est = times, est

    def estimate_at(self, times_s: np.ndarray) -> ObjectEstimate:
        i = np.searchsorted(self.times, times_s)
        e = self.est
        return ObjectEstimate(e.distance_mm[i], e.distance_std_mm[i], e.direction_proba[i],
                              e.depth_proba[i])


def _model(est: ObjectEstimate, n: int, config: DistanceEstimateConfig
           ) -> tuple[DistanceEstimateSensorModel, np.ndarray]:
    times = 0.01 * np.arange(n)
    model = DistanceEstimateSensorModel(config, BuildContext(
        "sm", np.random.default_rng(0), inputs={"est": _Fixed(times, est)}))
    return model, times


def test_reports_come_by_travel_spacing_and_at_a_class_change() -> None:
    x = 0.001 * np.arange(100)
    positions, headings, est = _approach(1000 * (0.2 - x), std_mm=1.0)
    config = DistanceEstimateConfig(report_spacing_m=0.01)
    model, times = _model(est, 100, config)
    probs = np.tile([1.0, 0.0], (100, 1))
    probs[70:] = [0.0, 1.0]  # the classifier says "near" from row 70 on
    located = LocatedMeasurement(times, positions, headings, probs, ("far", "near"))
    model.observe(located)
    # The first row, every crossing of 1 cm (rows 10, 20, ..., 90; some floats land a
    # row late) and the class change at row 70 (also a crossing): 10 reports.
    assert model.reported_rows == 10
    model.on_movement_end(None)  # type: ignore[arg-type]
    model.reported_rows = 0
    probs[70:] = [1.0, 0.0]
    probs[75] = [0.0, 1.0]  # a lone "near": reported, and the row after it too
    model.observe(LocatedMeasurement(times, positions, headings, probs, ("far", "near")))
    assert model.reported_rows == 12


def test_streaming_row_by_row_equals_one_batch_and_a_movement_end_restarts() -> None:
    x = 0.001 * np.arange(80)
    positions, headings, est = _approach(1000 * (0.1 - x), std_mm=1.0)
    config = DistanceEstimateConfig()
    model, times = _model(est, 80, config)
    probs = np.tile([1.0, 0.0], (80, 1))
    located = LocatedMeasurement(times, positions, headings, probs, ("far", "near"))
    whole = model.observe(located)
    model.reset()
    rows = [model.observe(located.select(slice(i, i + 1))) for i in range(80)]
    np.testing.assert_allclose(np.concatenate([r.points_m for r in rows]), whole.points_m)
    np.testing.assert_allclose(np.concatenate([r.weights for r in rows]), whole.weights)
    # Without a movement end the next rows would continue the window; after one, the
    # consistency restarts at 0 (no object until 2 cm of travel), so the first 10 rows of
    # a new movement place no object.
    model.on_movement_end(MovementResult.__new__(MovementResult))
    again = model.observe(located.select(slice(0, 10)))
    assert not (again.targets == 1).any()
