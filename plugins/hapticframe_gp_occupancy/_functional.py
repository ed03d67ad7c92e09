"""GP occupancy numerics as pure array functions (numpy/scipy only).

The latent occupancy ``f`` is a Gaussian process regressed on the targets mapped to
``t = 2 y - 1`` (1 occupied, -1 free), with a constant prior mean ``m0`` and per-point noise
variance ``noise / w`` (an observation of weight 0 says nothing). The occupancy is the
probit link of O'Callaghan and Ramos's GPOM (probabilistic least-squares classification):
``p = E[Phi(alpha f)]`` over the latent posterior ``N(mu, var)``, which is
``Phi(alpha mu / sqrt(1 + alpha^2 var))``; its standard deviation over the same posterior
is exact through Owen's T function (:func:`probit_moments`).

Two posteriors of ``f``:

- exact (:func:`exact_posterior`, :func:`exact_predict`): the Cholesky factor of the
  ``N x N`` kernel matrix, ``O(N^3)`` to build and ``O(N^2)`` per query point for the
  variance;
- inducing points (:func:`inducing_statistics`, :func:`inducing_predict`): the
  deterministic training conditional (DTC, Seeger et al. 2003; Quinonero-Candela and
  Rasmussen 2005) on ``M`` fixed inducing points ``Z``. The data enter only through
  ``S = K_zx W K_xz`` and ``r = K_zx W (t - m0)`` with ``W = diag(w) / noise``, which add
  over batches: streaming updates equal one fit to rounding, at ``O(n M^2)`` per batch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import cho_solve, cholesky, solve_triangular
from scipy.special import ndtr, ndtri, owens_t

__all__ = [
    "ExactPosterior",
    "InducingPosterior",
    "exact_posterior",
    "exact_predict",
    "inducing_grid",
    "inducing_posterior",
    "inducing_predict",
    "inducing_statistics",
    "latent_targets",
    "prior_mean_for_occupancy",
    "probit_moments",
    "rbf_kernel",
]

FloatArray = NDArray[np.float64]

#: Relative jitter added to kernel diagonals before a Cholesky factorisation.
JITTER = 1e-8


def rbf_kernel(a: FloatArray, b: FloatArray, length_scale_m: float, variance: float) -> FloatArray:
    """``variance exp(-|a - b|^2 / (2 l^2))`` between the rows of ``a`` (n, 2) and ``b`` (m, 2)."""
    a = np.asarray(a, dtype=np.float64) / length_scale_m
    b = np.asarray(b, dtype=np.float64) / length_scale_m
    # Differences, not |a|^2 + |b|^2 - 2 a.b: that form cancels catastrophically far from
    # the origin (a point 1e6 m away would lose its own kernel value).
    d2 = np.subtract.outer(a[:, 0], b[:, 0])
    d2 *= d2
    dy = np.subtract.outer(a[:, 1], b[:, 1])
    dy *= dy
    d2 += dy
    d2 *= -0.5
    np.exp(d2, out=d2)
    d2 *= variance
    return d2


def latent_targets(targets: ArrayLike) -> FloatArray:
    """Regression targets ``2 y - 1`` of occupancy targets ``y`` in [0, 1]."""
    return 2.0 * np.asarray(targets, dtype=np.float64) - 1.0


def prior_mean_for_occupancy(occupancy: float, link_scale: float, signal_variance: float) -> float:
    """The constant prior mean ``m0`` whose prior occupancy is ``occupancy``:
    ``Phi(alpha m0 / sqrt(1 + alpha^2 s^2)) = occupancy``."""
    return float(ndtri(occupancy) * np.sqrt(1.0 + link_scale**2 * signal_variance) / link_scale)


def probit_moments(
    mu: ArrayLike, var: ArrayLike, link_scale: float
) -> tuple[FloatArray, FloatArray]:
    """Mean and standard deviation of ``Phi(alpha f)`` for ``f ~ N(mu, var)``.

    The mean is ``Phi(h)`` with ``h = alpha mu / sqrt(1 + alpha^2 var)``. The second moment
    ``E[Phi(alpha f)^2]`` is a bivariate normal orthant probability,
    ``Phi(h) - 2 T(h, 1 / sqrt(1 + 2 alpha^2 var))`` (Owen's T), so the std needs no sampling.
    """
    m = np.asarray(mu, dtype=np.float64)
    s2 = link_scale**2 * np.maximum(np.asarray(var, dtype=np.float64), 0.0)
    h = link_scale * m / np.sqrt(1.0 + s2)
    mean = ndtr(h)
    second = mean - 2.0 * owens_t(h, 1.0 / np.sqrt(1.0 + 2.0 * s2))
    std = np.sqrt(np.clip(second - mean * mean, 0.0, 0.25))
    return mean, std


def _cholesky(matrix: FloatArray, what: str) -> FloatArray:
    """Lower Cholesky factor with a relative jitter, raised tenfold until it succeeds."""
    scale = max(float(np.mean(np.diag(matrix))), 1e-300)
    jitter = JITTER * scale
    for _ in range(8):
        try:
            return cholesky(matrix + jitter * np.eye(matrix.shape[0]), lower=True,
                            check_finite=False)
        except np.linalg.LinAlgError:
            jitter *= 10.0
    raise np.linalg.LinAlgError(f"the {what} is not positive definite even with jitter {jitter:g}")


@dataclass(frozen=True)
class ExactPosterior:
    """Exact GP posterior: training points, ``L`` with ``L L^T = K + noise W^-1``, and
    ``alpha = (K + noise W^-1)^-1 (t - m0)``."""

    points_m: FloatArray
    factor: FloatArray
    alpha: FloatArray


def exact_posterior(
    points_m: FloatArray,
    centred_targets: FloatArray,
    noise_variances: FloatArray,
    length_scale_m: float,
    signal_variance: float,
) -> ExactPosterior:
    """Factorise the ``N x N`` kernel matrix of ``points_m`` with per-point noise."""
    k = rbf_kernel(points_m, points_m, length_scale_m, signal_variance)
    k[np.diag_indices_from(k)] += noise_variances
    factor = _cholesky(k, "kernel matrix of the observations")
    alpha = cho_solve((factor, True), centred_targets, check_finite=False)
    return ExactPosterior(points_m, factor, alpha)


def exact_predict(
    posterior: ExactPosterior, queries_m: FloatArray, length_scale_m: float,
    signal_variance: float,
) -> tuple[FloatArray, FloatArray]:
    """Latent mean (without ``m0``) and variance at ``queries_m`` (q, 2)."""
    cross = rbf_kernel(queries_m, posterior.points_m, length_scale_m, signal_variance)
    mu = cross @ posterior.alpha
    v = solve_triangular(posterior.factor, cross.T, lower=True, check_finite=False)
    var = signal_variance - np.einsum("ij,ij->j", v, v)
    return mu, np.maximum(var, 0.0)


def inducing_grid(
    x_min: float, x_max: float, y_min: float, y_max: float, spacing_m: float
) -> FloatArray:
    """Inducing points on a regular grid covering the rectangle, edges included (x-major)."""
    nx = max(1, int(np.ceil((x_max - x_min) / spacing_m - 1e-9))) + 1
    ny = max(1, int(np.ceil((y_max - y_min) / spacing_m - 1e-9))) + 1
    xs = x_min + spacing_m * np.arange(nx) - 0.5 * (spacing_m * (nx - 1) - (x_max - x_min))
    ys = y_min + spacing_m * np.arange(ny) - 0.5 * (spacing_m * (ny - 1) - (y_max - y_min))
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel()])


def inducing_statistics(
    inducing_m: FloatArray,
    points_m: FloatArray,
    centred_targets: FloatArray,
    precisions: FloatArray,
    length_scale_m: float,
    signal_variance: float,
    chunk: int = 4096,
) -> tuple[FloatArray, FloatArray]:
    """``S = K_zx W K_xz`` (M, M) and ``r = K_zx W (t - m0)`` (M,) of one batch, with
    ``W = diag(precisions)``; rows are processed ``chunk`` at a time to bound memory."""
    m = inducing_m.shape[0]
    s = np.zeros((m, m))
    r = np.zeros(m)
    for start in range(0, points_m.shape[0], chunk):
        rows = slice(start, start + chunk)
        k = rbf_kernel(points_m[rows], inducing_m, length_scale_m, signal_variance)
        weighted = k * precisions[rows, None]
        s += weighted.T @ k
        r += weighted.T @ centred_targets[rows]
    return s, r


@dataclass(frozen=True)
class InducingPosterior:
    """DTC posterior on inducing points: ``beta = A^-1 r`` with ``A = K_zz + S``, and
    ``reduction = K_zz^-1 - A^-1``, by which the variance falls below the prior's."""

    inducing_m: FloatArray
    reduction: FloatArray
    beta: FloatArray


def inducing_posterior(
    inducing_m: FloatArray, s: FloatArray, r: FloatArray, length_scale_m: float,
    signal_variance: float,
) -> InducingPosterior:
    """Factorise ``K_zz`` and ``K_zz + S`` for :func:`inducing_predict`."""
    kzz = rbf_kernel(inducing_m, inducing_m, length_scale_m, signal_variance)
    kzz_factor = _cholesky(kzz, "kernel matrix of the inducing points")
    a_factor = _cholesky(kzz + s, "DTC precision matrix")
    beta = cho_solve((a_factor, True), r, check_finite=False)
    # One M x M matrix makes a query's variance one matrix product instead of two
    # triangular solves (half the flops, and GEMM runs faster than TRSM).
    identity = np.eye(inducing_m.shape[0])
    reduction = (cho_solve((kzz_factor, True), identity, check_finite=False)
                 - cho_solve((a_factor, True), identity, check_finite=False))
    reduction = 0.5 * (reduction + reduction.T)
    return InducingPosterior(inducing_m, reduction, beta)


def inducing_predict(
    posterior: InducingPosterior, queries_m: FloatArray, length_scale_m: float,
    signal_variance: float,
) -> tuple[FloatArray, FloatArray]:
    """DTC latent mean (without ``m0``) and variance at ``queries_m``:
    ``K_qz A^-1 r`` and ``k_qq - K_qz K_zz^-1 K_zq + K_qz A^-1 K_zq`` (the prior variance far
    from the inducing points, unlike the subset-of-regressors variance)."""
    cross = rbf_kernel(queries_m, posterior.inducing_m, length_scale_m, signal_variance)
    mu = cross @ posterior.beta
    var = signal_variance - np.einsum("ij,ij->i", cross @ posterior.reduction, cross)
    return mu, np.maximum(var, 0.0)
