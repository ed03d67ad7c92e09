"""The ``distance-estimate`` sensor model: each observation placed where the estimate says.

Where the failure-zone kernel puts the evidence of an interaction at the failure zone's
fixed rupture distance ahead of the fingertip, this sensor model puts it at the distance
the ``raking-estimator`` estimates, in the direction it estimates, weighted by how far the
estimate can be trusted there. Samples are *reported* by travel spacing
(``report_spacing_m``: the first sample of a movement, every crossing of a multiple of the
spacing, and any sample whose most probable class differs from the previous one, such as
the halt). For each reported sample with an estimate at its time:

- the estimate's *certainty* ``1 / (1 + (σ / s)^e)`` (``d`` and ``σ`` the estimated
  distance and its standard deviation, ``s`` = ``reference_std_m``, ``e`` =
  ``certainty_exponent``) and its *consistency*
  ``c = 1 / (1 + (spread / consistency_std_m)⁴)``, where ``spread`` is the root-mean-square
  spread of the object points ``p + d · u(heading)`` implied by the estimates of the last
  ``consistency_travel_m`` of the movement's travel (an object at rest stays put while the
  tool moves; an estimate that repeats one distance whatever the travel is not reading
  the object; NaN, or a movement that has not yet travelled that far: ``c = 0``);
- *object* observations (target 1) per direction class ``k`` at
  ``p + d · u(heading + bearing_k)`` and ``object_depth_m`` beyond (the object goes on
  behind its nearest outline point), weighted ``object_weight · P(k) · certainty · c``,
  when ``d`` is within ``max_range_m``;
- ``free_points`` *free* observations (target 0) evenly on the segment from the fingertip
  to ``d − 2σ`` straight ahead (the sand the estimate says is empty), weighted
  ``certainty · c``;
- ``free_points`` free observations up to ``untracked_free_m`` ahead, weighted
  ``untracked_free_weight · (1 − c)`` (an estimate that does not follow the travel: no
  object within the reach where the forces rise);
- one free observation at the fingertip, weighted ``path_free_weight``.

A classifier input that is not an estimator (anything without ``estimate_at``) gives no
estimate: the model then falls back to the failure zone's rule, one object observation at
``fallback_distance_m`` straight ahead weighted by the probability of any non-background
class, so a chain of other plugins still maps (every sample, as before).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import (
    BuildContext,
    LocatedMeasurement,
    MovementResult,
    Observations,
    SensorModel,
)

from ._config import DistanceEstimateConfig
from ._model import ObjectEstimate

__all__ = ["DistanceEstimateSensorModel", "ObjectEstimator", "certainty_weights",
           "consistency_weights", "place_observations"]

FloatArray = NDArray[np.float64]


@runtime_checkable
class ObjectEstimator(Protocol):
    """A component that can say its object estimate at given times (NaN rows: none)."""

    def estimate_at(self, times_s: NDArray[np.float64]) -> ObjectEstimate: ...


def consistency_weights(spread_m: FloatArray, config: DistanceEstimateConfig) -> FloatArray:
    """``1 / (1 + (spread / consistency_std_m)⁴)``; NaN or negative spreads give 0.

    Raises
    ------
    ValueError
        When ``spread_m`` is not one-dimensional.
    """
    spread = np.asarray(spread_m, dtype=np.float64)
    if spread.ndim != 1:
        raise ValueError(f"spread_m must be one-dimensional, got shape {spread.shape}")
    ok = np.isfinite(spread) & (spread >= 0)
    ratio = np.where(ok, spread, 0.0) / config.consistency_std_m
    out: FloatArray = np.where(ok, 1.0 / (1.0 + ratio ** 4), 0.0)
    return out


def certainty_weights(std_m: FloatArray, config: DistanceEstimateConfig) -> FloatArray:
    """``1 / (1 + (σ / reference_std_m) ^ certainty_exponent)``; NaN or negative σ give 0.

    Raises
    ------
    ValueError
        When ``std_m`` is not one-dimensional.
    """
    sigma = np.asarray(std_m, dtype=np.float64)
    if sigma.ndim != 1:
        raise ValueError(f"std_m must be one-dimensional, got shape {sigma.shape}")
    ok = np.isfinite(sigma) & (sigma >= 0)
    ratio = np.where(ok, sigma, 0.0) / config.reference_std_m
    out: FloatArray = np.where(ok, 1.0 / (1.0 + ratio ** config.certainty_exponent), 0.0)
    return out


class _Track:
    """One movement's bookkeeping: travel, reports and the implied points' spread.

    Rows given together or one at a time give the same result (plain-float loop; the
    closed loop sends one row at a time).
    """

    def __init__(self, config: DistanceEstimateConfig) -> None:
        self.config = config
        self._previous: tuple[float, float] | None = None
        self._previous_class = -1
        self._travel = 0.0
        self._history: list[tuple[float, float, float]] = []  # (travel, qx, qy)

    def step(self, positions_m: FloatArray, headings_rad: FloatArray, distance_m: FloatArray,
             classes: NDArray[np.intp] | None) -> tuple[NDArray[np.bool_], FloatArray]:
        """Which rows to report and each row's consistency weight."""
        c = self.config
        n = len(positions_m)
        report = np.zeros(n, dtype=bool)
        spread = np.full(n, np.nan)
        window = c.consistency_travel_m
        for i in range(n):
            x, y = float(positions_m[i, 0]), float(positions_m[i, 1])
            if not (math.isfinite(x) and math.isfinite(y)):
                continue  # no position: nothing to report, travel unchanged
            cls = -1 if classes is None else int(classes[i])
            if self._previous is None:
                report[i] = True
            else:
                before = self._travel
                self._travel = before + math.hypot(x - self._previous[0],
                                                   y - self._previous[1])
                spacing = c.report_spacing_m
                report[i] = (spacing <= 0 or math.floor(self._travel / spacing)
                             > math.floor(before / spacing) or cls != self._previous_class)
            self._previous = (x, y)
            self._previous_class = cls
            d, h = float(distance_m[i]), float(headings_rad[i])
            if math.isfinite(d) and math.isfinite(h):
                self._history.append((self._travel, x + d * math.cos(h), y + d * math.sin(h)))
            else:
                self._history.append((self._travel, math.nan, math.nan))
            if window <= 0:
                spread[i] = 0.0
                continue
            while len(self._history) > 1 and self._history[1][0] <= self._travel - window:
                self._history.pop(0)
            if self._history[0][0] > self._travel - window:
                continue  # the movement has not yet travelled a whole window
            q = np.array([(qx, qy) for _, qx, qy in self._history])
            if np.all(np.isfinite(q)):
                spread[i] = math.sqrt(float(np.mean(np.sum((q - q.mean(axis=0)) ** 2,
                                                           axis=1))))
        return report, consistency_weights(spread, c)


def _blocks(positions_m: FloatArray, headings_rad: FloatArray, est: ObjectEstimate,
            consistency: FloatArray, config: DistanceEstimateConfig
            ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Per row: points ``(n, 3D + 2F + 1, 2)``, targets and weights ``(n, 3D + 2F + 1)``
    (weight 0: nothing there; ``D`` object depths): the three direction classes' object
    points (at ``d``, then ``d + object_depth_m``), the free points before
    the estimate, the free points of an estimate that does not follow the travel, and the
    free point at the fingertip."""
    n = len(positions_m)
    d = np.maximum(est.distance_mm / 1000.0, 0.0)
    sigma = est.distance_std_mm / 1000.0
    located = np.all(np.isfinite(positions_m), axis=1) & np.isfinite(headings_rad)
    ok = np.isfinite(d) & np.isfinite(sigma) & located
    d = np.where(ok, d, 0.0)
    sigma = np.where(ok, sigma, 0.0)
    h = np.where(located, headings_rad, 0.0)
    trust = np.where(ok, np.clip(consistency, 0.0, 1.0), 0.0)
    certainty = np.where(ok, certainty_weights(sigma, config), 0.0) * trust
    p = np.where(located[:, None], positions_m, 0.0)
    f = config.free_points
    depths = (0.0, config.object_depth_m) if config.object_depth_m > 0 else (0.0,)
    o = 3 * len(depths)
    points = np.zeros((n, o + 2 * f + 1, 2))
    targets = np.zeros((n, o + 2 * f + 1))
    weights = np.zeros((n, o + 2 * f + 1))
    near = d <= config.max_range_m
    column = 0
    for k, bearing in enumerate(np.radians(config.direction_bearings_deg)):
        angle = h + bearing
        direction = np.column_stack([np.cos(angle), np.sin(angle)])
        weight = np.where(near, config.object_weight * est.direction_proba[:, k] * certainty,
                          0.0)
        for depth in depths:
            points[:, column] = p + (d + depth)[:, None] * direction
            targets[:, column] = 1.0
            weights[:, column] = weight
            column += 1
    ahead = np.column_stack([np.cos(h), np.sin(h)])
    if f:
        fractions = (np.arange(f) + 1.0) / (f + 1.0)
        reach = np.clip(d - 2.0 * sigma, 0.0, config.max_range_m)
        points[:, o:o + f] = p[:, None, :] + (reach[:, None] * fractions[None, :])[..., None] * (
            ahead[:, None, :])
        weights[:, o:o + f] = np.where(reach > 0, certainty, 0.0)[:, None]
        untracked = np.where(located, config.untracked_free_weight * (1.0 - trust), 0.0)
        if config.untracked_free_m > 0:
            points[:, o + f:o + 2 * f] = p[:, None, :] + (
                config.untracked_free_m * fractions)[None, :, None] * ahead[:, None, :]
            weights[:, o + f:o + 2 * f] = untracked[:, None]
    points[:, -1] = p
    weights[:, -1] = np.where(located, config.path_free_weight, 0.0)
    return points, targets, weights


def _flatten(points: FloatArray, targets: FloatArray, weights: FloatArray,
             min_weight: float) -> Observations:
    used = weights.reshape(-1) > min_weight
    return Observations(points.reshape(-1, 2)[used], targets.reshape(-1)[used],
                        weights.reshape(-1)[used])


def _check_rows(positions_m: FloatArray, headings_rad: FloatArray,
                est: ObjectEstimate) -> None:
    n = len(positions_m)
    if positions_m.shape != (n, 2) or headings_rad.shape != (n,) or any(
            len(a) != n for a in (est.distance_mm, est.distance_std_mm, est.direction_proba)):
        raise ValueError(f"positions {positions_m.shape}, headings {headings_rad.shape} and "
                         f"{len(est.distance_mm)} estimates do not match row for row")


def place_observations(positions_m: FloatArray, headings_rad: FloatArray,
                       est: ObjectEstimate, config: DistanceEstimateConfig) -> Observations:
    """The observations of :class:`DistanceEstimateSensorModel` for the rows of one
    movement with estimates, row by row (a reported row's object points, then its free
    points); rows without an estimate or a position place nothing.

    Raises
    ------
    ValueError
        When the arrays do not match row for row.
    """
    positions = np.asarray(positions_m, dtype=np.float64)
    headings = np.asarray(headings_rad, dtype=np.float64)
    _check_rows(positions, headings, est)
    report, consistency = _Track(config).step(positions, headings,
                                              est.distance_mm / 1000.0, None)
    points, targets, weights = _blocks(positions, headings, est, consistency, config)
    ok = np.isfinite(est.distance_mm) & np.isfinite(est.distance_std_mm) & report
    return _flatten(points[ok], targets[ok], weights[ok], config.min_weight)


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
        self.reported_rows = 0
        self._track = _Track(config)

    def reset(self) -> None:
        """Forget the movement's travel and estimates."""
        self._track = _Track(self.config)

    def on_movement_end(self, result: MovementResult) -> None:
        """The next movement starts a new travel count and a new window of estimates."""
        self._track = _Track(self.config)

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        n = len(measurement)
        if n == 0:
            return Observations(np.empty((0, 2)), np.empty(0))
        if self._estimator is not None:
            est = self._estimator.estimate_at(measurement.timestamps_s)
        else:
            est = ObjectEstimate(np.full(n, np.nan), np.full(n, np.nan), np.zeros((n, 3)),
                                 np.zeros((n, 2)))
        positions = np.asarray(measurement.positions_m, dtype=np.float64)
        headings = np.asarray(measurement.headings_rad, dtype=np.float64)
        probabilities = np.asarray(measurement.probabilities, dtype=np.float64)
        classes = np.argmax(np.nan_to_num(probabilities, nan=-1.0), axis=1)
        report, consistency = self._track.step(positions, headings,
                                               est.distance_mm / 1000.0, classes)
        points, targets, weights = _blocks(positions, headings, est, consistency, self.config)
        missing = ~np.isfinite(est.distance_mm)
        self.fallback_rows += int(missing.sum())
        # Without an estimate: the failure zone's rule, one point at a fixed distance ahead
        # at every sample (a chain without an estimator reports as before).
        fallback = positions + self.config.fallback_distance_m * np.column_stack(
            [np.cos(headings), np.sin(headings)])
        interaction = np.where(missing, 1.0 - probabilities[:, 0], 0.0)
        keep = report & ~missing
        weights = np.where(keep[:, None], weights, 0.0)
        self.reported_rows += int(keep.sum())
        return _flatten(np.concatenate([points, fallback[:, None, :]], axis=1),
                        np.concatenate([targets, np.ones((n, 1))], axis=1),
                        np.concatenate([weights, interaction[:, None]], axis=1),
                        self.config.min_weight)

    def finalize(self, outcome: Any) -> Mapping[str, Any]:
        return {f"{self.id}_fallback_rows": self.fallback_rows,
                f"{self.id}_reported_rows": self.reported_rows}
