"""Bayesian Hilbert map numerics as pure array functions (numpy/scipy only).

Model
-----
Occupancy at a point ``x`` is ``sigma(w^T phi(x))`` with RBF hinge features
``phi_m(x) = exp(-||x - h_m||^2 / (2 l_m^2))`` (one length scale ``l_m`` per hinge, so
``gamma_m = 1 / (2 l_m^2)``), optionally followed by a constant bias feature. The weights
have a Gaussian belief ``N(m, S)`` kept in information form: precision ``Lambda = S^-1``
and shift ``eta = Lambda m``.

Variational EM (Jaakkola–Jordan bound)
--------------------------------------
A soft target ``y`` in [0, 1] with weight ``w`` contributes ``w (y log sigma(a) +
(1 - y) log sigma(-a))`` = ``w (t a + log sigma(-a) + a/2)`` with ``t = y - 1/2``; the
symmetric part is bounded below by the JJ quadratic in ``a`` with local parameter ``xi``.
For a batch with prior ``(Lambda0, eta0)`` held fixed, each iteration sets::

    Lambda = Lambda0 + 2 sum_n w_n lambda(xi_n) phi_n phi_n^T
    eta    = eta0 + sum_n w_n t_n phi_n
    xi_n   = sqrt((phi_n^T m)^2 + phi_n^T S phi_n)

and stops when the relative change of ``xi`` falls below a tolerance or an iteration cap
is hit. The posterior becomes the next batch's prior exactly once. (The public reference
code feeds every iteration's posterior back as the prior, which counts a batch once per
iteration and shrinks the weight variances; that is deliberately not done here.)

All linear algebra goes through a Cholesky factor of the precision: posterior means by
``cho_solve``, predictive variances ``phi^T S phi = ||L^-1 phi||^2`` by triangular solves,
weight samples by ``m + L^-T z``. No matrix is inverted explicitly.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
from numpy.typing import ArrayLike, NDArray
from scipy.linalg import blas, lapack
from scipy.special import expit

from ._windowed import DenseRows, WindowedRows, all_finite

__all__ = [
    "GaussianWeights",
    "UpdateInfo",
    "activation_samples",
    "cholesky_with_jitter",
    "hinge_axis",
    "hinge_features",
    "hinge_points",
    "jj_lambda",
    "monte_carlo_probability",
    "predictive_moments",
    "probit_kappa",
    "probit_probability",
    "sample_weights",
    "separable_hinge_features",
    "surrogate_std",
    "variational_update",
    "xi_from_belief",
]

FloatArray = NDArray[np.float64]

#: Below this |xi| the series of lambda(xi) is used; the tanh form loses digits near 0.
_LAMBDA_SERIES_BELOW = 1e-4
#: Relative diagonal jitter of the first Cholesky retry (multiplied by 100 per retry).
_JITTER_START = 1e-12
_JITTER_RETRIES = 6


# --- hinges and features ----------------------------------------------------------------


def hinge_axis(low: float, high: float, spacing: float) -> FloatArray:
    """Hinge coordinates along one axis: both edges included plus one spacing of padding.

    The axis runs ``low - spacing, low, low + spacing, ...`` up to the first value at or
    beyond ``high``, then one more value. A width that is not a multiple of ``spacing``
    ends on the first hinge past ``high``.
    """
    if not (np.isfinite(low) and np.isfinite(high) and high > low):
        raise ValueError(f"need finite low < high, got {low!r}, {high!r}")
    if not (np.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing must be positive and finite, got {spacing!r}")
    # The small slack keeps 0.75 / 0.05 from rounding up to 16 intervals.
    intervals = max(1, int(np.ceil((high - low) / spacing - 1e-9)))
    return low + spacing * np.arange(-1, intervals + 2, dtype=np.float64)


def hinge_points(xs: FloatArray, ys: FloatArray) -> FloatArray:
    """``(nx * ny, 2)`` hinge locations, x-major (hinge ``i * ny + j`` is ``(xs[i], ys[j])``)."""
    gx, gy = np.meshgrid(np.asarray(xs, float), np.asarray(ys, float), indexing="ij")
    return np.column_stack([gx.ravel(), gy.ravel()])


def _as_points(points: ArrayLike) -> FloatArray:
    p = np.asarray(points, dtype=np.float64)
    if p.ndim == 1 and p.shape == (2,):
        p = p[None, :]
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"points must have shape (n, 2), got {p.shape}")
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or infinity")
    return p


def _gaussian_factor(offsets: FloatArray, length_scale: float | FloatArray) -> FloatArray:
    # Dividing before squaring keeps tiny length scales from overflowing 1/(2 l^2).
    with np.errstate(over="ignore", under="ignore"):
        scaled = offsets / length_scale
        return np.exp(-0.5 * np.minimum(scaled * scaled, 1e4))


def hinge_features(
    points: ArrayLike, hinges: ArrayLike, length_scales: ArrayLike, bias: bool = False
) -> FloatArray:
    """Dense RBF hinge features for arbitrary hinges.

    Parameters
    ----------
    points : (n, 2) array_like
    hinges : (M, 2) array_like
    length_scales : float or (M,) array_like
        Kernel length scale per hinge in metres (``gamma = 1 / (2 l^2)``).
    bias : bool
        Append a constant-1 column.

    Returns
    -------
    (n, M + bias) float64
    """
    p = _as_points(points)
    h = np.asarray(hinges, dtype=np.float64).reshape(-1, 2)
    scales = np.broadcast_to(np.asarray(length_scales, dtype=np.float64), (h.shape[0],))
    if np.any(~np.isfinite(scales)) or np.any(scales <= 0):
        raise ValueError("length scales must be positive and finite")
    fx = _gaussian_factor(p[:, :1] - h[None, :, 0], scales)
    fy = _gaussian_factor(p[:, 1:] - h[None, :, 1], scales)
    phi = fx * fy
    if bias:
        phi = np.hstack([phi, np.ones((p.shape[0], 1))])
    return phi


def _axis_factors(
    coordinates: FloatArray, axis: FloatArray, length_scales: FloatArray
) -> dict[float, FloatArray]:
    """exp(-(c - axis)^2 / (2 l^2)) for each distinct length scale l."""
    offsets = coordinates[:, None] - axis[None, :]
    return {
        float(scale): _gaussian_factor(offsets, float(scale)) for scale in np.unique(length_scales)
    }


def separable_hinge_features(
    points: ArrayLike,
    xs: FloatArray,
    ys: FloatArray,
    length_scales: FloatArray,
    bias: bool = False,
) -> FloatArray:
    """Hinge features for a hinge grid, using that the 2-D Gaussian factorises per axis.

    Same values as :func:`hinge_features` on :func:`hinge_points` ``(xs, ys)`` but with
    ``2 n (nx + ny)`` exponentials per distinct length scale instead of ``n nx ny``.

    Parameters
    ----------
    points : (n, 2) array_like
    xs, ys : (nx,), (ny,) float64
        Hinge axes.
    length_scales : (nx, ny) float64
        Length scale of each hinge; few distinct values keep this fast.
    bias : bool
    """
    p = _as_points(points)
    scales = np.asarray(length_scales, dtype=np.float64)
    if scales.shape != (xs.size, ys.size):
        raise ValueError(f"length_scales must have shape {(xs.size, ys.size)}, got {scales.shape}")
    if np.any(~np.isfinite(scales)) or np.any(scales <= 0):
        raise ValueError("length scales must be positive and finite")
    n, m = p.shape[0], xs.size * ys.size
    first = float(scales.flat[0])
    if np.all(scales == first):  # one length scale (the default): a single outer product
        fx = _gaussian_factor(p[:, :1] - xs[None, :], first)
        fy = _gaussian_factor(p[:, 1:] - ys[None, :], first)
        phi = np.empty((n, m + int(bias)))
        np.multiply(fx[:, :, None], fy[:, None, :], out=phi[:, :m].reshape(n, xs.size, ys.size))
        if bias:
            phi[:, m] = 1.0
        return phi
    factors_x = _axis_factors(p[:, 0], xs, scales)
    factors_y = _axis_factors(p[:, 1], ys, scales)
    flat_scales = scales.ravel()
    values, counts = np.unique(flat_scales, return_counts=True)
    # The most common length scale fills every column as an outer product; the hinges
    # with other length scales (typically few) are then overwritten column by column.
    common = float(values[np.argmax(counts)])
    phi = np.empty((n, m + int(bias)))
    np.multiply(
        factors_x[common][:, :, None],
        factors_y[common][:, None, :],
        out=phi[:, :m].reshape(n, xs.size, ys.size),
    )
    for value in values:
        if float(value) == common:
            continue
        columns = np.flatnonzero(flat_scales == value)
        ix, iy = np.divmod(columns, ys.size)
        phi[:, columns] = factors_x[float(value)][:, ix] * factors_y[float(value)][:, iy]
    if bias:
        phi[:, m] = 1.0
    return phi


# --- Jaakkola–Jordan pieces -------------------------------------------------------------


def jj_lambda(xi: ArrayLike) -> FloatArray:
    """``lambda(xi) = tanh(xi / 2) / (4 xi)``, even in ``xi``, with ``lambda(0) = 1/8``.

    Below ``|xi| = 1e-4`` the series ``1/8 - xi^2 / 96`` is used (its next term,
    ``xi^4 / 960``, is below 1e-18 there), so the function is smooth and finite at 0.
    """
    x = np.abs(np.asarray(xi, dtype=np.float64))
    out = np.empty_like(x)
    small = x < _LAMBDA_SERIES_BELOW
    out[small] = 0.125 - x[small] ** 2 / 96.0
    large = ~small
    out[large] = np.tanh(0.5 * x[large]) / (4.0 * x[large])
    return out


def cholesky_with_jitter(matrix: FloatArray) -> FloatArray:
    """Lower Cholesky factor; on failure retries with a tiny, growing diagonal jitter.

    Raises
    ------
    numpy.linalg.LinAlgError
        When the matrix is not positive definite even after the retries (or not finite).
    """
    a = np.asarray(matrix, dtype=np.float64)
    if not all_finite(a):
        raise np.linalg.LinAlgError("matrix to factorise contains NaN or infinity")
    # LAPACK directly: scipy.linalg.cholesky's checks cost as much as the factorisation
    # at D ~ 235. potrf leaves the strict upper triangle untouched, so it is cleared.
    lower, info = lapack.dpotrf(a, lower=1, clean=1)
    if info == 0:
        return lower
    scale = float(np.mean(np.abs(np.diag(a)))) or 1.0
    jitter = _JITTER_START * scale
    for _ in range(_JITTER_RETRIES):
        try:
            return sla.cholesky(a + jitter * np.eye(a.shape[0]), lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            jitter *= 100.0
    raise np.linalg.LinAlgError("matrix is not positive definite, even with diagonal jitter")


@dataclass(frozen=True)
class GaussianWeights:
    """A Gaussian belief over the weights in information form, with its Cholesky factor.

    Attributes
    ----------
    precision : (D, D) float64
        ``Lambda = S^-1`` (a property: a belief built from its Cholesky factor alone, as a
        tiled map rebuilds the tiles it packed, computes it when first read).
    shift : (D,) float64
        ``eta = Lambda m``.
    cholesky : (D, D) float64
        Lower factor ``L`` with ``L L^T = Lambda``.
    mean : (D,) float64
        ``m``.
    diagonal : bool
        True when the precision is known to be diagonal (an untouched prior); predictive
        variances then skip the triangular solve.
    """

    shift: FloatArray
    cholesky: FloatArray
    mean: FloatArray
    diagonal: bool = False
    _cache: dict[str, FloatArray] = field(default_factory=dict, compare=False, repr=False)

    @property
    def precision(self) -> FloatArray:
        """``Lambda = S^-1``, or ``L L^T`` (BLAS ``syrk``) when built without it."""
        cached = self._cache.get("precision")
        if cached is None:
            product = blas.dsyrk(1.0, self.cholesky, lower=1)  # L L^T, lower triangle
            cached = np.tril(product) + np.tril(product, -1).T
            self._cache["precision"] = cached
        return cached

    @classmethod
    def from_information(cls, precision: FloatArray, shift: FloatArray) -> GaussianWeights:
        """Factorise ``precision`` and solve for the mean."""
        lower = cholesky_with_jitter(precision)
        mean, info = lapack.dpotrs(lower, shift, lower=1)
        if info != 0:  # cannot happen for a factor potrf produced; keep the checked path
            mean = sla.cho_solve((lower, True), shift, check_finite=False)
        return cls(shift, lower, mean, _cache={"precision": precision})

    @classmethod
    def isotropic(
        cls, dimension: int, variance: float | FloatArray, mean: float | FloatArray = 0.0
    ) -> GaussianWeights:
        """Prior with independent weights of the given variance(s) and mean(s) (default 0)."""
        var = np.broadcast_to(np.asarray(variance, dtype=np.float64), (dimension,))
        if np.any(~np.isfinite(var)) or np.any(var <= 0):
            raise ValueError("prior variances must be positive and finite")
        centre = np.broadcast_to(np.asarray(mean, dtype=np.float64), (dimension,)).copy()
        if not np.all(np.isfinite(centre)):
            raise ValueError("prior means must be finite")
        precision = np.diag(1.0 / var)
        root = np.diag(np.sqrt(1.0 / var))
        return cls(centre / var, root, centre, diagonal=True, _cache={"precision": precision})

    @property
    def dimension(self) -> int:
        return int(self.mean.size)

    def variances(self) -> FloatArray:
        """Marginal weight variances ``diag(S)`` (column norms of ``L^-1``)."""
        if self.diagonal:
            return 1.0 / np.diag(self.precision)
        inverse_factor = sla.solve_triangular(
            self.cholesky, np.eye(self.dimension), lower=True, check_finite=False
        )
        return np.einsum("ij,ij->j", inverse_factor, inverse_factor)

    @property
    def has_covariance(self) -> bool:
        """True when :meth:`covariance` is already computed (it costs nothing then)."""
        return "covariance" in self._cache

    def covariance(self) -> FloatArray:
        """The full covariance ``S`` from the Cholesky factor (LAPACK ``potri``), cached.

        ``potri`` inverts the triangular factor and multiplies it out (what ``cho_solve``
        with the identity does, at half the cost). The returned array is shared between
        calls: do not modify it.
        """
        cached = self._cache.get("covariance")
        if cached is not None:
            return cached
        if self.diagonal:
            cov = np.diag(1.0 / np.diag(self.precision))
        else:
            lower, info = lapack.dpotri(self.cholesky, lower=1)
            if info != 0:
                cov = sla.cho_solve(
                    (self.cholesky, True), np.eye(self.dimension), check_finite=False
                )
            else:
                cov = np.tril(lower) + np.tril(lower, -1).T
        cov.setflags(write=False)
        self._cache["covariance"] = cov
        return cov


@dataclass(frozen=True)
class UpdateInfo:
    """Diagnostics of one variational update."""

    iterations: int
    converged: bool
    relative_change: float
    xi: FloatArray


def predictive_moments(
    belief: GaussianWeights, features: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Mean and variance of the activation ``a = phi^T w`` under the belief.

    The variance is ``||L^-1 phi||^2``, computed with one triangular solve for all rows.
    """
    phi = np.asarray(features, dtype=np.float64)
    mu = phi @ belief.mean
    if phi.shape[0] == 0:
        return mu, np.zeros(0)
    if belief.diagonal:
        return mu, (phi * phi) @ (1.0 / np.diag(belief.precision))
    return mu, _whitened_squared_norms(belief.cholesky, phi)


def _whitened_squared_norms(lower: FloatArray, phi: FloatArray) -> FloatArray:
    """``||L^-1 phi_n||^2`` for every row ``phi_n``: one LAPACK ``trtrs`` for all rows (what
    ``scipy.linalg.solve_triangular`` calls, without its argument handling)."""
    whitened, info = lapack.dtrtrs(lower, phi.T, lower=1)
    if info != 0:  # a zero on the diagonal: cannot happen for a factor potrf produced
        whitened = sla.solve_triangular(lower, phi.T, lower=True, check_finite=False)
    return np.einsum("ij,ij->j", whitened, whitened)


def xi_from_belief(belief: GaussianWeights, features: FloatArray) -> FloatArray:
    """``xi_n = sqrt(max(0, (phi_n^T m)^2 + phi_n^T S phi_n))``."""
    mu, var = predictive_moments(belief, features)
    return np.sqrt(np.maximum(0.0, mu * mu + var))


def variational_update(
    prior: GaussianWeights,
    features: FloatArray,
    targets: FloatArray,
    weights: FloatArray | None = None,
    *,
    max_iterations: int = 10,
    tolerance: float = 1e-2,
    xi_initial: FloatArray | None = None,
) -> tuple[GaussianWeights, UpdateInfo]:
    """Fuse one batch of soft-labelled points into a Gaussian weight belief.

    Parameters
    ----------
    prior : GaussianWeights
        The batch prior; it is held fixed while ``xi`` is iterated.
    features : (n, D) float64, DenseRows or WindowedRows
        Feature rows (see :mod:`hapticframe_bhm._windowed`).
    targets : (n,) float64
        Soft occupancy targets in [0, 1].
    weights : (n,) float64, optional
        Non-negative per-point weights (default 1).
    max_iterations : int
        Cap on the number of posterior computations (>= 1).
    tolerance : float
        Stop when ``||xi_new - xi|| <= tolerance * ||xi||``.
    xi_initial : (n,) float64, optional
        Starting local parameters; default: the prior predictive
        ``sqrt((phi^T m0)^2 + phi^T S0 phi)``, where the JJ bound is tight under the prior.

    Returns
    -------
    posterior : GaussianWeights
    info : UpdateInfo
    """
    rows = features if isinstance(features, (DenseRows, WindowedRows)) else DenseRows(features)
    y = np.asarray(targets, dtype=np.float64)
    n, d = rows.count, rows.dimension
    if d != prior.dimension:
        raise ValueError(f"features have {d} columns, the belief has {prior.dimension} weights")
    if y.shape != (n,):
        raise ValueError(f"targets must have shape ({n},), got {y.shape}")
    w = np.ones(n) if weights is None else np.asarray(weights, dtype=np.float64)
    if w.shape != (n,):
        raise ValueError(f"weights must have shape ({n},), got {w.shape}")
    if not (rows.all_finite() and np.all(np.isfinite(y)) and np.all(np.isfinite(w))):
        raise ValueError("features, targets and weights must be finite")
    if n and (y.min() < 0 or y.max() > 1 or w.min() < 0):
        raise ValueError("targets must lie in [0, 1] and weights must be non-negative")
    if max_iterations < 1:
        raise ValueError("max_iterations must be at least 1")
    if n == 0:
        return prior, UpdateInfo(0, True, 0.0, np.zeros(0))

    shift = prior.shift + rows.weighted_sum(w * (y - 0.5))
    xi = _xi(prior, rows) if xi_initial is None else np.abs(np.asarray(xi_initial, float))
    if xi.shape != (n,):
        raise ValueError(f"xi_initial must have shape ({n},), got {xi.shape}")
    change = np.inf
    for iteration in range(1, max_iterations + 1):
        precision = prior.precision + rows.gram(2.0 * w * jj_lambda(xi))
        posterior = GaussianWeights.from_information(precision, shift)
        if iteration == max_iterations:
            break
        xi_new = _xi(posterior, rows)
        change = float(np.linalg.norm(xi_new - xi) / max(np.linalg.norm(xi), 1e-300))
        xi = xi_new
        if change <= tolerance:
            # The posterior for xi_new differs from this one by O(tolerance); keep it.
            return posterior, UpdateInfo(iteration, True, change, xi)
    return posterior, UpdateInfo(max_iterations, change <= tolerance, change, xi)


def _xi(belief: GaussianWeights, rows: Any) -> FloatArray:
    """``xi_n`` of :func:`xi_from_belief` over feature rows (dense or windowed).

    Dense rows (small batches) use one triangular solve with the precision's Cholesky factor;
    windowed rows (large batches) the cached covariance, ``phi^T S phi`` in ``O(n K^4)``.
    """
    mu = rows.dot(belief.mean)
    if belief.diagonal:
        var = rows.quadratic_diagonal(1.0 / np.diag(belief.precision))
    elif isinstance(rows, DenseRows) and rows.count <= 4 * belief.dimension:
        # A few rows: one triangular solve (n D^2 / 2 flops) beats a product with the
        # covariance (n D^2) and needs no covariance at all.
        var = _whitened_squared_norms(belief.cholesky, rows.matrix)
    else:
        var = rows.quadratic(belief.covariance())
    return np.sqrt(np.maximum(0.0, mu * mu + var))


# --- prediction -------------------------------------------------------------------------


def probit_kappa(var_a: FloatArray) -> FloatArray:
    """MacKay's ``kappa = (1 + pi var / 8)^(-1/2)``."""
    return 1.0 / np.sqrt(1.0 + (np.pi / 8.0) * np.maximum(np.asarray(var_a, float), 0.0))


def probit_probability(mu_a: FloatArray, var_a: FloatArray) -> FloatArray:
    """Deterministic approximation of ``E[sigma(a)]``, ``a ~ N(mu, var)``: ``sigma(kappa mu)``."""
    return expit(probit_kappa(var_a) * np.asarray(mu_a, float))


def surrogate_std(mu_a: FloatArray, var_a: FloatArray) -> FloatArray:
    """Deterministic stand-in for the std of ``sigma(a)``: ``p (1 - p) kappa sqrt(var)``."""
    kappa = probit_kappa(var_a)
    p = expit(kappa * np.asarray(mu_a, float))
    return p * (1.0 - p) * kappa * np.sqrt(np.maximum(np.asarray(var_a, float), 0.0))


def sample_weights(belief: GaussianWeights, rng: np.random.Generator, count: int) -> FloatArray:
    """``(D, count)`` draws ``m + L^-T z`` from the belief, ``z`` standard normal."""
    if count < 1:
        raise ValueError("count must be at least 1")
    z = rng.standard_normal((belief.dimension, count))
    offsets = sla.solve_triangular(belief.cholesky, z, lower=True, trans="T", check_finite=False)
    return belief.mean[:, None] + offsets


def activation_samples(features: FloatArray, weight_samples: FloatArray) -> FloatArray:
    """``(n, K)`` activations of ``n`` feature rows under ``K`` weight samples."""
    return np.asarray(features, float) @ weight_samples


def monte_carlo_probability(activations: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Sample mean and std (``ddof=1``) of ``sigma(a)`` along the last axis."""
    a = np.asarray(activations, dtype=np.float64)
    if a.shape[-1] < 2:
        raise ValueError("need at least two samples for a standard deviation")
    p = expit(a)
    mean = p.mean(axis=-1)
    std = p.std(axis=-1, ddof=1)
    return np.clip(mean, 0.0, 1.0), std
