"""The beliefs behind a Bayesian Hilbert map: one interface, a dense posterior and tiles.

:class:`BayesianHilbertMap` holds one :class:`HilbertBelief`: a :class:`DenseBelief` (one
full-covariance posterior over every hinge, this module) or, for regions with more than
``dense_weights_max`` weights, :class:`~hapticframe_bhm._tiled.TiledBeliefs` (dense beliefs
over overlapping tiles of the hinges). The map checks its inputs and sets the BLAS threads;
the belief does the arithmetic. The update rule, region-dependent smoothing and the
uncertainty estimate are described in :mod:`hapticframe_bhm._map`.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import Observations, Region

from . import _functional as fn
from ._checks import MAX_WEIGHTS
from ._config import BayesianHilbertMapConfig
from ._separable import grid_activation_samples, grid_predictive_moments
from ._windowed import DenseRows, WindowedRows, window_half_width

__all__ = ["DenseBelief", "HilbertBelief", "grid_axes"]

FloatArray = NDArray[np.float64]

#: Targets above this count as interaction observations for region-dependent smoothing.
_INTERACTION_TARGET = 0.5
#: Smallest batch whose variational update uses windowed features (below it, dense BLAS
#: products over all hinges are cheaper than the per-window loop).
_WINDOWED_MIN_ROWS = 1000
#: Query rows processed at once: at most 16,384, and at most this many feature entries per
#: chunk (2 M doubles, 16 MB), so that a chunk's (rows x D) matrices stay small when D is large.
_QUERY_CHUNK = 16384
_QUERY_ENTRIES = 1 << 21


class HilbertBelief(Protocol):
    """What a Bayesian Hilbert map asks of its weight belief (dense or tiled).

    Points are checked, finite ``(q, 2)`` float64 arrays; grids are given by their axes.
    """

    #: What the last variational update reported (None before one, and for tiles).
    last_update_info: fn.UpdateInfo | None

    def reset(self) -> None:
        """Back to the prior and free-regime hinges."""

    def update(self, observations: Observations) -> None:
        """Fuse a non-empty batch."""

    def query(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Occupancy mean and std at ``points``."""

    def log_odds(self, points: FloatArray) -> FloatArray:
        """``kappa mu_a`` at ``points``."""

    def grid_moments(self, xs: FloatArray, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Mean and std, ``(len(ys), len(xs))``, on the grid of axes ``xs`` and ``ys``."""

    @property
    def interaction_hinges(self) -> NDArray[np.bool_]:
        """``(nx, ny)`` True where a hinge uses the interaction length scale."""

    @property
    def length_scales(self) -> FloatArray:
        """``(nx, ny)`` kernel length scale of every hinge, in metres."""

    @property
    def batches_fused(self) -> int:
        """Batches fused since the last reset."""

    @property
    def refits(self) -> int:
        """Refits of all data since the last reset."""


def grid_axes(points: FloatArray) -> tuple[FloatArray, FloatArray] | None:
    """``(xs, ys)`` when ``points`` is the row-major grid ``meshgrid(xs, ys)`` (x fastest),
    with at least 64 points and both axes strictly increasing; else None."""
    n = points.shape[0]
    if n < 64:
        return None
    y0 = points[0, 1]
    # The first row: the leading run of points with the first point's y.
    nx = int(np.argmax(points[:, 1] != y0)) if np.any(points[:, 1] != y0) else n
    if nx < 2 or n % nx:
        return None
    grid = points.reshape(n // nx, nx, 2)
    xs, ys = grid[0, :, 0], grid[:, 0, 1]
    if grid.shape[0] < 2 or np.any(np.diff(xs) <= 0) or np.any(np.diff(ys) <= 0):
        return None
    if not (np.array_equal(grid[:, :, 0], np.broadcast_to(xs, grid.shape[:2]))
            and np.array_equal(grid[:, :, 1], np.broadcast_to(ys[:, None], grid.shape[:2]))):
        return None
    return xs.copy(), ys.copy()


class DenseBelief:
    """One full-covariance Gaussian belief over the weights of the hinge grid ``xs x ys``.

    Parameters
    ----------
    config : BayesianHilbertMapConfig
    region : Region
        The region the hinges cover (named in errors).
    xs, ys : (nx,), (ny,) float64
        The hinge axes; hinge ``i * ny + j`` is ``(xs[i], ys[j])``, the bias weight last.
    rng : numpy.random.Generator
        Draws the Monte-Carlo weight samples.
    name : str
        The map's id, for errors.
    prior : GaussianWeights or None
        The prior to start from (tiles of one size share one; it is only read); None builds
        it from the config.

    Attributes
    ----------
    posterior : GaussianWeights
        The current belief (the prior after a reset). A tile whose belief was packed away
        (:mod:`._tiled`) has none until it is unpacked.
    prior : GaussianWeights
    last_update_info : UpdateInfo or None
    """

    def __init__(
        self,
        config: BayesianHilbertMapConfig,
        region: Region,
        xs: FloatArray,
        ys: FloatArray,
        rng: np.random.Generator,
        name: str,
        prior: fn.GaussianWeights | None = None,
    ) -> None:
        self.config = config
        self.region = region
        self.xs, self.ys = xs, ys
        self.hinges = fn.hinge_points(xs, ys)
        dimension = self.hinges.shape[0] + int(config.bias)
        if dimension > MAX_WEIGHTS:
            raise ValueError(
                f"map {name!r}: {dimension} weights (hinge spacing "
                f"{config.hinge_spacing_m} m over {region}) exceed the dense limit of "
                f"{MAX_WEIGHTS}; increase hinge_spacing_m or lower dense_weights_max"
            )
        self._rng = rng
        if prior is None:
            prior_mean = np.zeros(dimension)
            if config.bias:
                prior_mean[-1] = float(
                    np.log(config.prior_occupancy / (1.0 - config.prior_occupancy)))
            prior = fn.GaussianWeights.isotropic(dimension, config.prior_variance, prior_mean)
        self.prior = prior
        self.reset()

    # --- state --------------------------------------------------------------------------

    def reset(self) -> None:
        self.last_update_info: fn.UpdateInfo | None = None
        self._interaction = np.zeros((self.xs.size, self.ys.size), dtype=bool)
        self._learned_scales: FloatArray | None = None
        self._learned_at = 0
        self.posterior = self.prior
        self._history: list[Observations] = []
        self._batches = 0
        self._weight_samples: FloatArray | None = None
        self._refits = 0

    @property
    def interaction_hinges(self) -> NDArray[np.bool_]:
        return self._interaction.copy()

    @property
    def length_scales(self) -> FloatArray:
        cfg = self.config
        if self._learned_scales is not None:
            return self._learned_scales.copy()
        return np.where(self._interaction, cfg.length_scale_interaction_m, cfg.length_scale_free_m)

    @property
    def batches_fused(self) -> int:
        """Batches fused since the last reset (a refit counts as one)."""
        return self._batches

    @property
    def refits(self) -> int:
        return self._refits

    def features(self, points_m: Any) -> FloatArray:
        """Feature rows of ``points_m`` under the current length scales."""
        return fn.separable_hinge_features(
            points_m, self.xs, self.ys, self.length_scales, self.config.bias
        )

    # --- updates ------------------------------------------------------------------------

    def update(self, observations: Observations) -> None:
        if self.config.automorphing_kernels:
            self._history.append(observations)
            seen = sum(len(batch) for batch in self._history)
            if self._batches == 0 or seen >= 2 * self._learned_at:
                self._learn_length_scales(seen)
                return
        if self.config.region_dependent_smoothing:
            self._history.append(observations)
            switched = self._switched_hinges(observations)
            if switched.any():
                self._interaction |= switched
                self._refit()
                return
        self._fuse(observations, first=self._batches == 0)

    def _switched_hinges(self, observations: Observations) -> NDArray[np.bool_]:
        """Hinges that enter the interaction regime with this batch (rule 2 of the map)."""
        flags = np.zeros(self._interaction.shape, dtype=bool)
        if self._batches > 0:
            # p > 0.5 under the probit mean exactly when the mean activation is positive.
            activation = self.features(self.hinges) @ self.posterior.mean
            flags |= activation.reshape(flags.shape) > 0.0
        hits = (observations.targets > _INTERACTION_TARGET) & (observations.weights > 0)
        if hits.any():
            points = observations.points_m[hits]
            radius = self.config.interaction_radius_m
            near = np.zeros(self.hinges.shape[0], dtype=bool)
            for start in range(0, points.shape[0], 1024):
                block = points[start : start + 1024]
                d2 = (block[:, None, 0] - self.hinges[None, :, 0]) ** 2 + (
                    block[:, None, 1] - self.hinges[None, :, 1]
                ) ** 2
                near |= (d2 <= radius * radius).any(axis=0)
            flags |= near.reshape(flags.shape)
        return flags & ~self._interaction

    def _learn_length_scales(self, seen: int) -> None:
        """Learn the hinges' length scales on all data and refit (:mod:`._automorph`)."""
        from ._automorph import learn_length_scales, length_scale_levels

        cfg = self.config
        everything = Observations.concatenate(self._history)
        levels = length_scale_levels(cfg.length_scale_free_m, *cfg.automorphing_range,
                                     cfg.automorphing_levels)
        scales, self.posterior, self.last_update_info = learn_length_scales(
            everything.points_m, everything.targets, everything.weights,
            self.xs, self.ys, self.length_scales, cfg.length_scale_free_m,
            levels, self.prior, bias=cfg.bias, iterations=cfg.automorphing_iterations,
            max_iterations=cfg.max_iterations_first, tolerance=cfg.tolerance,
        )
        self._learned_scales = scales
        self._learned_at = seen
        self._batches = 1
        self._refits += 1
        self._weight_samples = None

    def _refit(self) -> None:
        everything = Observations.concatenate(self._history)
        self.posterior = self.prior
        self._batches = 0
        self._refits += 1
        self._fuse(everything, first=True)

    def _rows(self, points_m: FloatArray) -> Any:
        """Feature rows of ``points_m`` for the variational update: windowed when every hinge
        has one length scale, a window holds under half the hinges and the batch is large
        enough for the per-window bookkeeping to pay off; else dense (BLAS)."""
        scales = self.length_scales
        spacing = self.config.hinge_spacing_m
        large = points_m.shape[0] >= _WINDOWED_MIN_ROWS
        if large and np.all(scales == scales.flat[0]):
            half = window_half_width(float(scales.flat[0]), spacing)
            k = 2 * half + 1
            fits = k <= min(self.xs.size, self.ys.size)
            if fits and k * k <= self.hinges.shape[0] // 2:
                return WindowedRows(
                    points_m, self.xs, self.ys, float(scales.flat[0]), self.config.bias, half,
                )
        return DenseRows(self.features(points_m))

    def _fuse(self, observations: Observations, *, first: bool) -> None:
        cfg = self.config
        phi = self._rows(observations.points_m)
        cap = cfg.max_iterations_first if first else cfg.max_iterations_update
        self.posterior, self.last_update_info = fn.variational_update(
            self.posterior,
            phi,
            observations.targets,
            observations.weights,
            max_iterations=cap,
            tolerance=cfg.tolerance,
        )
        self._batches += 1
        self._weight_samples = None

    # --- queries ------------------------------------------------------------------------

    def _samples(self) -> FloatArray:
        if self._weight_samples is None:
            self._weight_samples = fn.sample_weights(
                self.posterior, self._rng, self.config.monte_carlo_samples
            )
        return self._weight_samples

    def query(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Mean and std at ``points``; a row-major grid takes the separable path."""
        axes = grid_axes(points)
        if axes is not None:
            mean_grid, std_grid = self.grid_moments(*axes)
            return mean_grid.reshape(-1), std_grid.reshape(-1)
        return self._point_moments(points)

    def _points_cheaper(self, cells: int) -> bool:
        """True when ``cells`` grid cells cost less point by point (``cells * D^2``) than
        through the covariance the separable path needs (about ``D^3 / 3`` unless cached)."""
        belief = self.posterior
        if belief.diagonal or belief.has_covariance:
            return False
        return 3 * cells < belief.dimension

    def _point_moments(self, points: FloatArray) -> tuple[FloatArray, FloatArray]:
        mean = np.empty(points.shape[0])
        std = np.empty(points.shape[0])
        chunk = max(256, min(_QUERY_CHUNK, _QUERY_ENTRIES // self.posterior.dimension))
        for start in range(0, points.shape[0], chunk):
            rows = slice(start, start + chunk)
            phi = self.features(points[rows])
            mu, var = fn.predictive_moments(self.posterior, phi)
            mean[rows] = fn.probit_probability(mu, var)
            if self.config.std_method == "surrogate":
                std[rows] = fn.surrogate_std(mu, var)
            else:
                activations = fn.activation_samples(phi, self._samples())
                std[rows] = fn.monte_carlo_probability(activations)[1]
        return mean, std

    def log_odds(self, points: FloatArray) -> FloatArray:
        if points.shape[0] == 0:
            return np.empty(0)
        mu, var = fn.predictive_moments(self.posterior, self.features(points))
        return fn.probit_kappa(var) * mu

    def grid_moments(self, xs: FloatArray, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
        if self._points_cheaper(xs.size * ys.size):
            # A coarse grid (a large map's snapshot: a few cells per tile) costs less point
            # by point, one triangular solve, than through the full covariance (O(D^3)).
            points = np.column_stack([np.tile(xs, ys.size), np.repeat(ys, xs.size)])
            mean, std = self._point_moments(points)
            return mean.reshape(ys.size, xs.size), std.reshape(ys.size, xs.size)
        args = (xs, ys, self.xs, self.ys, self.length_scales)
        mu, var = grid_predictive_moments(*args, self.posterior, self.config.bias)
        mean = fn.probit_probability(mu, var)
        if self.config.std_method == "surrogate":
            std = fn.surrogate_std(mu, var)
        else:
            activations = grid_activation_samples(*args, self._samples(), self.config.bias)
            std = fn.monte_carlo_probability(activations)[1]
        return mean, std
