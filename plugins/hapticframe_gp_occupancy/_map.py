"""The ``gp-occupancy`` map: Gaussian-process occupancy (GPOM), the thesis's road not taken.

The thesis chose Hilbert maps because they are "simpler and faster" than Gaussian-process
occupancy maps; this map is that alternative, so that ``hapticframe bench bhm`` can measure
the claim. It regresses a GP on the targets (``2y - 1``) and squashes the latent posterior
through a probit link (O'Callaghan and Ramos's GPOM, see :mod:`._functional`).

Updates keep every observation (a GP conditions on all of them):

- ``exact`` (``method: exact``, or ``auto`` with at most ``exact_max_observations``): the
  posterior is refactorised from all observations at the first query after an update,
  ``O(N^3)``; a query costs ``O(N^2)`` per point for the variance. Streaming and one fit
  give the same map exactly.
- ``inducing`` (``method: inducing``, or ``auto`` beyond the limit): the DTC approximation on
  a grid of inducing points over the region (``inducing_spacing_m``). Each batch adds its
  statistics in ``O(n M^2)``; the first query after an update factorises two ``M x M``
  matrices. Under ``auto``, the switch computes the statistics of all stored observations
  once.

``learn_hyperparameters`` fits length scale and signal variance by scikit-learn's
marginal-likelihood optimiser whenever the exact posterior is rebuilt (the noise stays
``noise_variance / w``, so that weights keep their meaning, and the prior mean stays the one
the configured values give).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.kinds import (
    BuildContext,
    Map,
    MapEstimate,
    Observations,
    Region,
    RunOutcome,
    query_points,
)
from hapticframe.threads import blas_threads

from . import _functional as fn
from ._config import GPOccupancyConfig

__all__ = ["GPOccupancyMap"]

FloatArray = NDArray[np.float64]

#: Default region when neither the config nor a scene gives one (thesis: 75 x 50 cm).
#: Kernel entries (query rows x training or inducing points) evaluated at once: 2 M doubles.
_QUERY_ENTRIES = 1 << 21





class GPOccupancyMap(Map):
    """Gaussian-process occupancy map: exact on small sets, inducing points on large ones.

    Built as ``GPOccupancyMap(config, context)``; see the module docstring. Deterministic:
    it draws no random numbers.
    """

    config: GPOccupancyConfig

    def __init__(self, config: GPOccupancyConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._region = context.map_region(config.region)
        r = self._region
        self._inducing = fn.inducing_grid(r.x_min_m, r.x_max_m, r.y_min_m, r.y_max_m,
                                          config.inducing_spacing_m)
        count = self._inducing.shape[0]
        if config.method != "exact" and count > config.max_inducing_points:
            raise ValueError(
                f"map {context.id!r}: inducing spacing {config.inducing_spacing_m:g} m gives "
                f"{count} inducing points over the {r.size_m[0]:.3g} x {r.size_m[1]:.3g} m "
                f"region, more than max_inducing_points ({config.max_inducing_points}); "
                "increase inducing_spacing_m or map a smaller region"
            )
        self._prior_mean = fn.prior_mean_for_occupancy(
            config.prior_occupancy, config.link_scale, config.signal_variance)
        self.reset()

    # --- state --------------------------------------------------------------------------

    def reset(self) -> None:
        """Forget all observations (and learned hyperparameters)."""
        self._points: list[FloatArray] = []
        self._targets: list[FloatArray] = []
        self._precisions: list[FloatArray] = []
        self._count = 0
        self._statistics: tuple[FloatArray, FloatArray] | None = None
        self._posterior: fn.ExactPosterior | fn.InducingPosterior | None = None
        self._length_scale = self.config.length_scale_m
        self._signal_variance = self.config.signal_variance

    @property
    def region(self) -> Region:
        return self._region

    @property
    def observation_count(self) -> int:
        """Observations of positive weight fused since the last reset."""
        return self._count

    @property
    def inducing_points(self) -> FloatArray:
        """The ``(M, 2)`` inducing points (used by the inducing path only)."""
        return self._inducing.copy()

    @property
    def method_in_use(self) -> Literal["prior", "exact", "inducing"]:
        """Which posterior answers queries now ('prior' before any observation)."""
        if self._count == 0:
            return "prior"
        method = self.config.method
        if method == "auto":
            return "exact" if self._count <= self.config.exact_max_observations else "inducing"
        return method

    @property
    def hyperparameters(self) -> dict[str, float]:
        """Length scale (m), signal and noise variance in use (learned ones when learning)."""
        return {"length_scale_m": self._length_scale,
                "signal_variance": self._signal_variance,
                "noise_variance": self.config.noise_variance}

    # --- updates ------------------------------------------------------------------------

    def update(self, observations: Observations) -> None:
        """Add a batch of observations; the posterior is rebuilt at the next query."""
        if not isinstance(observations, Observations):
            raise TypeError(f"update expects Observations, got {type(observations).__name__}")
        keep = observations.weights > 0
        if not np.any(keep):
            return
        points = observations.points_m[keep]
        centred = fn.latent_targets(observations.targets[keep]) - self._prior_mean
        precisions = observations.weights[keep] / self.config.noise_variance
        self._points.append(points)
        self._targets.append(centred)
        self._precisions.append(precisions)
        self._count += int(points.shape[0])
        self._posterior = None
        if self.method_in_use != "inducing":
            return
        with blas_threads(self.config.blas_threads):
            if self._statistics is None:
                # The first batch beyond the exact limit (or the first of an inducing map):
                # the statistics of everything stored so far.
                self._statistics = self._batch_statistics(
                    *(np.concatenate(parts) for parts in
                      (self._points, self._targets, self._precisions)))
            else:
                s, r = self._batch_statistics(points, centred, precisions)
                self._statistics = (self._statistics[0] + s, self._statistics[1] + r)

    def _batch_statistics(
        self, points: FloatArray, centred: FloatArray, precisions: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        return fn.inducing_statistics(self._inducing, points, centred, precisions,
                                      self._length_scale, self._signal_variance)

    def condition(self) -> None:
        """Build the posterior now (else the first query after an update does)."""
        with blas_threads(self.config.blas_threads):
            self._ensure_posterior()

    def _ensure_posterior(self) -> fn.ExactPosterior | fn.InducingPosterior | None:
        if self._posterior is not None or self._count == 0:
            return self._posterior
        if self.method_in_use == "inducing":
            assert self._statistics is not None
            s, r = self._statistics
            self._posterior = fn.inducing_posterior(self._inducing, s, r, self._length_scale,
                                                    self._signal_variance)
            return self._posterior
        points = np.concatenate(self._points)
        centred = np.concatenate(self._targets)
        noise = 1.0 / np.concatenate(self._precisions)
        if self.config.learn_hyperparameters and points.shape[0] >= 2:
            self._learn(points, centred, noise)
        self._posterior = fn.exact_posterior(points, centred, noise, self._length_scale,
                                             self._signal_variance)
        return self._posterior

    def _learn(self, points: FloatArray, centred: FloatArray, noise: FloatArray) -> None:
        """Length scale and signal variance by scikit-learn's marginal-likelihood optimiser,
        started from the configured values, within a factor 10 (100 for the variance)."""
        try:
            from sklearn.exceptions import ConvergenceWarning
            from sklearn.gaussian_process import GaussianProcessRegressor
            from sklearn.gaussian_process.kernels import RBF, ConstantKernel
        except ImportError as exc:
            raise RuntimeError(
                f"map {self.id!r}: learn_hyperparameters needs scikit-learn: pip install "
                "'hapticframe[learn]', or set learn_hyperparameters: false"
            ) from exc

        cfg = self.config
        kernel = ConstantKernel(cfg.signal_variance,
                                (cfg.signal_variance / 100, cfg.signal_variance * 100)) * RBF(
            cfg.length_scale_m, (cfg.length_scale_m / 10, cfg.length_scale_m * 10))
        regressor = GaussianProcessRegressor(kernel, alpha=noise, optimizer="fmin_l_bfgs_b",
                                             n_restarts_optimizer=0, copy_X_train=False)
        with warnings.catch_warnings():
            # A value at a bound is the bound we chose, not news to the run's user.
            warnings.simplefilter("ignore", ConvergenceWarning)
            regressor.fit(points, centred)
        params = regressor.kernel_.get_params()
        self._signal_variance = float(params["k1__constant_value"])
        self._length_scale = float(params["k2__length_scale"])

    # --- queries ------------------------------------------------------------------------

    def latent_moments(self, points_m: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """Posterior mean (prior mean included) and variance of the latent ``f``."""
        p = query_points(points_m)
        mu = np.full(p.shape[0], self._prior_mean)
        var = np.full(p.shape[0], self._signal_variance)
        with blas_threads(self.config.blas_threads):
            posterior = self._ensure_posterior()
            if posterior is None or p.shape[0] == 0:
                return mu, var
            columns = (posterior.points_m if isinstance(posterior, fn.ExactPosterior)
                       else posterior.inducing_m).shape[0]
            chunk = max(64, _QUERY_ENTRIES // columns)
            for start in range(0, p.shape[0], chunk):
                rows = slice(start, start + chunk)
                if isinstance(posterior, fn.ExactPosterior):
                    m, v = fn.exact_predict(posterior, p[rows], self._length_scale,
                                            self._signal_variance)
                else:
                    m, v = fn.inducing_predict(posterior, p[rows], self._length_scale,
                                               self._signal_variance)
                mu[rows] += m
                var[rows] = v
        return mu, var

    def _query(self, points_m: FloatArray) -> MapEstimate:
        """Occupancy ``E[Phi(alpha f)]`` and its exact standard deviation at ``points_m``."""
        mu, var = self.latent_moments(points_m)
        mean, std = fn.probit_moments(mu, var, self.config.link_scale)
        return MapEstimate(mean, std)

    def probability_grid(
        self, spacing_m: float
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """Mean and std on the cell centres of a regular grid over the region.

        Returns ``xs`` (nx,), ``ys`` (ny,), and ``mean``, ``std`` of shape ``(ny, nx)`` (row
        ``j`` is ``y = ys[j]``, image layout).
        """
        xs, ys = self._region.grid(spacing_m)
        gx, gy = np.meshgrid(xs, ys, indexing="xy")
        estimate = self.query(np.column_stack([gx.ravel(), gy.ravel()]))
        shape = (ys.size, xs.size)
        return xs, ys, estimate.mean.reshape(shape), estimate.std.reshape(shape)

    # --- results ------------------------------------------------------------------------

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write ``gp_mean.png`` and ``gp_std.png`` into ``outcome.out_dir``; no metrics."""
        if not outcome.figures:
            return {}
        from ._plots import save_map_figures

        r = self._region
        area = (r.x_max_m - r.x_min_m) * (r.y_max_m - r.y_min_m)
        # At most about 250,000 pixels: an exact GP's variance costs O(N) per pixel.
        spacing = max(0.005, float(np.sqrt(area / 2.5e5)))
        xs, ys, mean, std = self.probability_grid(spacing)
        save_map_figures(
            Path(outcome.out_dir), r, xs, ys, mean, std,
            outlines=[] if outcome.scene is None else [o.outline() for o in outcome.scene.objects],
            movements=outcome.movements,
            outline_level=outcome.outline_level,
            method=self.method_in_use,
        )
        return {}
