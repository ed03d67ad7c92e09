"""The ``distance-estimate`` sensor model: each observation placed where the estimate says.

Where the failure-zone kernel puts the evidence of an interaction at the failure zone's
fixed rupture distance ahead of the fingertip, this sensor model puts it at the distance
the ``raking-estimator`` estimates, in the direction it estimates, weighted by how sure the
estimate is. For each located sample with an estimate at its time:

- one *object* observation (target 1) per direction class ``k`` at
  ``p + d · u(heading + bearing_k)``, weighted ``P(k) · s² / (s² + σ²)`` (``d`` and ``σ``
  the estimated distance and its standard deviation, ``s`` = ``reference_std_m``), when
  ``d`` is within ``max_range_m``;
- ``free_points`` *free* observations (target 0) evenly on the segment from the fingertip
  to ``d − 2σ`` straight ahead (the sand the estimate says is empty), weighted the same way.

A classifier input that is not an estimator (anything without ``estimate_at``) gives no
estimate: the model then falls back to the failure zone's rule, one object observation at
``fallback_distance_m`` straight ahead weighted by the probability of any non-background
class, so a chain of other plugins still maps.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import BuildContext, LocatedMeasurement, Observations, SensorModel

from ._config import DistanceEstimateConfig
from ._model import ObjectEstimate

__all__ = ["DistanceEstimateSensorModel", "ObjectEstimator", "place_observations"]


@runtime_checkable
class ObjectEstimator(Protocol):
    """A component that can say its object estimate at given times (NaN rows: none)."""

    def estimate_at(self, times_s: NDArray[np.float64]) -> ObjectEstimate: ...


def _blocks(positions_m: NDArray[np.float64], headings_rad: NDArray[np.float64],
            est: ObjectEstimate, config: DistanceEstimateConfig
            ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Per row: points ``(n, 3 + F, 2)``, targets and weights ``(n, 3 + F)`` (weight 0:
    nothing there), the three direction classes' object points first, then the free ones."""
    n = len(positions_m)
    d = np.maximum(est.distance_mm / 1000.0, 0.0)
    sigma = est.distance_std_mm / 1000.0
    ok = np.isfinite(d) & np.isfinite(sigma) & np.all(np.isfinite(positions_m), axis=1)
    d = np.where(ok, d, 0.0)
    sigma = np.where(ok, sigma, 0.0)
    s2 = config.reference_std_m ** 2
    certainty = np.where(ok, s2 / (s2 + sigma ** 2), 0.0)
    p = np.where(ok[:, None], positions_m, 0.0)
    f = config.free_points
    points = np.zeros((n, 3 + f, 2))
    targets = np.zeros((n, 3 + f))
    weights = np.zeros((n, 3 + f))
    near = d <= config.max_range_m
    for k, bearing in enumerate(np.radians(config.direction_bearings_deg)):
        angle = headings_rad + bearing
        points[:, k] = p + d[:, None] * np.column_stack([np.cos(angle), np.sin(angle)])
        targets[:, k] = 1.0
        weights[:, k] = np.where(near, est.direction_proba[:, k] * certainty, 0.0)
    if f:
        reach = np.clip(d - 2.0 * sigma, 0.0, config.max_range_m)
        fractions = (np.arange(f) + 1.0) / (f + 1.0)
        ahead = np.column_stack([np.cos(headings_rad), np.sin(headings_rad)])
        points[:, 3:] = p[:, None, :] + (reach[:, None] * fractions[None, :])[..., None] * (
            ahead[:, None, :])
        weights[:, 3:] = np.where(reach > 0, certainty, 0.0)[:, None]
    return points, targets, weights


def _flatten(points: NDArray[np.float64], targets: NDArray[np.float64],
             weights: NDArray[np.float64], min_weight: float) -> Observations:
    used = weights.reshape(-1) > min_weight
    return Observations(points.reshape(-1, 2)[used], targets.reshape(-1)[used],
                        weights.reshape(-1)[used])


def place_observations(positions_m: NDArray[np.float64], headings_rad: NDArray[np.float64],
                       est: ObjectEstimate, config: DistanceEstimateConfig) -> Observations:
    """The observations of :class:`DistanceEstimateSensorModel` for rows with estimates,
    row by row (a row's object points, then its free points)."""
    return _flatten(*_blocks(positions_m, headings_rad, est, config), config.min_weight)


class DistanceEstimateSensorModel(SensorModel):
    """Observations at the estimated distance and direction (see the module docstring).

    Parameters
    ----------
    config : DistanceEstimateConfig
    context : BuildContext
        Inputs: a classifier (ideally a ``raking-estimator``) and the robot.
    """

    def __init__(self, config: DistanceEstimateConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._estimator = next((c for c in context.inputs.values()
                                if isinstance(c, ObjectEstimator)), None)
        self.fallback_rows = 0

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        n = len(measurement)
        if n == 0:
            return Observations(np.empty((0, 2)), np.empty(0))
        if self._estimator is not None:
            est = self._estimator.estimate_at(measurement.timestamps_s)
        else:
            est = ObjectEstimate(np.full(n, np.nan), np.full(n, np.nan), np.zeros((n, 3)),
                                 np.zeros((n, 2)))
        points, targets, weights = _blocks(measurement.positions_m, measurement.headings_rad,
                                           est, self.config)
        missing = ~np.isfinite(est.distance_mm)
        self.fallback_rows += int(missing.sum())
        # Without an estimate: the failure zone's rule, one point at a fixed distance ahead.
        h = measurement.headings_rad
        fallback = measurement.positions_m + self.config.fallback_distance_m * np.column_stack(
            [np.cos(h), np.sin(h)])
        interaction = np.where(missing, 1.0 - measurement.probabilities[:, 0], 0.0)
        return _flatten(np.concatenate([points, fallback[:, None, :]], axis=1),
                        np.concatenate([targets, np.ones((n, 1))], axis=1),
                        np.concatenate([weights, interaction[:, None]], axis=1),
                        self.config.min_weight)

    def finalize(self, outcome: Any) -> Mapping[str, Any]:
        return {f"{self.id}_fallback_rows": self.fallback_rows}
