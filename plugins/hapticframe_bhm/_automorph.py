"""Automorphing kernels: a length scale per hinge learned from the data (numpy only).

Senanayake and Ramos's automorphing Bayesian Hilbert maps let every hinge's kernel widen
where the occupancy changes slowly and narrow where it changes fast (thesis section
3.5.2.2, Fig. 3.5 c and h). This module learns them by alternating, on all observations
so far:

1. the variational posterior of the weights under the current length scales
   (:func:`hapticframe_bhm._functional.variational_update`, from the prior);
2. one ascent step on ``log l_m`` of every hinge for the expected log likelihood at the
   posterior mean, ``sum_n w_n (y_n - sigma(a_n)) m_m phi_nm d_nm^2 / l_m^2``, plus a
   Gaussian prior on ``log l_m`` centred on the stationary length scale (standard deviation
   ``log 2``, so that hinges no observation reaches return to it). The step is the gradient
   divided by its standard deviation over the hinges, clipped to +-0.3 in ``log l``;
3. rounding ``l_m`` to the nearest of a few log-spaced levels, which keeps the number of
   distinct length scales small: the features, the grid queries and the Monte-Carlo
   activations of :mod:`._separable` cost one pass per distinct length scale.

A final posterior is fitted under the learned length scales. This is a maximum a
posteriori estimate of the length scales at the posterior mean, not the paper's full
variational treatment; it costs ``iterations + 1`` fits of all data (see the map's
``automorphing_kernels`` setting for when it runs).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.special import expit

from . import _functional as fn

__all__ = ["learn_length_scales", "length_scale_levels"]

FloatArray = NDArray[np.float64]

#: Standard deviation of the prior on log l around the stationary length scale.
_LOG_PRIOR_STD = math.log(2.0)
#: Largest change of log l in one step.
_MAX_STEP = 0.3


def length_scale_levels(base: float, low: float, high: float, count: int) -> FloatArray:
    """``count`` log-spaced length scales from ``base * low`` to ``base * high``, with
    ``base`` itself among them when it lies in the range."""
    levels = base * np.geomspace(low, high, count)
    if low <= 1.0 <= high:
        levels[np.argmin(np.abs(np.log(levels / base)))] = base
    return levels


def _snap(scales: FloatArray, levels: FloatArray) -> FloatArray:
    index = np.argmin(np.abs(np.log(scales)[..., None] - np.log(levels)), axis=-1)
    return np.asarray(levels[index], dtype=np.float64)


def learn_length_scales(
    points: FloatArray,
    targets: FloatArray,
    weights: FloatArray,
    xs: FloatArray,
    ys: FloatArray,
    initial: FloatArray,
    base: float,
    levels: FloatArray,
    prior: fn.GaussianWeights,
    *,
    bias: bool,
    iterations: int,
    max_iterations: int,
    tolerance: float,
) -> tuple[FloatArray, fn.GaussianWeights, fn.UpdateInfo]:
    """Per-hinge length scales ``(nx, ny)`` and the posterior fitted under them.

    Parameters
    ----------
    points, targets, weights : (n, 2), (n,), (n,) float64
        Every observation the scales are learned from.
    xs, ys : (nx,), (ny,) float64
        The hinge axes.
    initial : (nx, ny) float64
        Starting length scales.
    base : float
        The stationary length scale (centre of the prior on ``log l``).
    levels : (k,) float64
        Length scales the result is rounded to.
    prior : GaussianWeights
        Prior of the weights (every fit starts from it).
    bias, iterations, max_iterations, tolerance
        Bias feature; ascent steps; variational iteration cap and tolerance of each fit.
    """
    scales = _snap(np.asarray(initial, dtype=np.float64), levels)
    nx, ny = xs.size, ys.size
    dx2 = (points[:, 0:1] - xs[None, :]) ** 2
    dy2 = (points[:, 1:2] - ys[None, :]) ** 2
    distance2 = (dx2[:, :, None] + dy2[:, None, :]).reshape(points.shape[0], nx * ny)
    for _ in range(iterations):
        phi = fn.separable_hinge_features(points, xs, ys, scales, bias)
        belief, _ = fn.variational_update(prior, phi, targets, weights,
                                          max_iterations=max_iterations, tolerance=tolerance)
        residual = weights * (targets - expit(phi @ belief.mean))
        flat = scales.ravel()
        hinge_phi = phi[:, : nx * ny]
        slope = belief.mean[: nx * ny] * (residual @ (hinge_phi * distance2)) / flat**2
        log_scale = np.log(flat)
        slope -= (log_scale - math.log(base)) / _LOG_PRIOR_STD**2
        spread = float(np.std(slope))
        if spread <= 0.0:
            break
        step = np.clip(slope / spread, -_MAX_STEP, _MAX_STEP)
        scales = _snap(np.exp(log_scale + step).reshape(nx, ny), levels)
    phi = fn.separable_hinge_features(points, xs, ys, scales, bias)
    belief, info = fn.variational_update(prior, phi, targets, weights,
                                         max_iterations=max_iterations, tolerance=tolerance)
    return scales, belief, info
