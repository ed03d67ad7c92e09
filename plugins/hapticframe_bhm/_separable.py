"""Fast BHM prediction on rectangular query grids (pure numpy).

On a hinge grid with one length scale per hinge, the feature of query ``(x_a, y_b)`` at
hinge ``(i, j)`` is ``gx_l[a, i] * gy_l[b, j]`` with ``l = l_ij``: the 2-D Gaussian
factorises per axis. With few distinct length scales (one or two), the feature matrix of
a ``qx x qy`` query grid is a masked sum of Kronecker products, and the predictive mean,
variance and weight-sample activations reduce to small tensor contractions:

- mean ``sum_l Gx_l (M o mask_l) Gy_l^T`` instead of a ``(qx qy) x D`` product;
- variance ``phi^T S phi`` contracted axis by axis, ``O(qx D^2 + qx qy ny^2)`` instead of
  ``O(qx qy D^2)``.

The variance needs the weight covariance ``S`` itself; it is obtained from the Cholesky
factor of the precision by triangular solves (:meth:`GaussianWeights.covariance`), never
by inverting the precision. Results equal the dense path of :mod:`._functional` to
rounding (tested).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ._functional import GaussianWeights, _gaussian_factor

__all__ = ["grid_activation_samples", "grid_predictive_moments"]

FloatArray = NDArray[np.float64]

#: Doubles in each intermediate block of the variance contraction.
_ENTRIES = 1 << 21


def _axis_blocks(
    query_xs: FloatArray,
    query_ys: FloatArray,
    hinge_xs: FloatArray,
    hinge_ys: FloatArray,
    length_scales: FloatArray,
) -> list[tuple[FloatArray, FloatArray, FloatArray]]:
    """Per distinct length scale: (Gx (qx, nx), Gy (qy, ny), hinge mask (nx, ny))."""
    scales = np.asarray(length_scales, dtype=np.float64)
    if scales.shape != (hinge_xs.size, hinge_ys.size):
        raise ValueError(
            f"length_scales must have shape {(hinge_xs.size, hinge_ys.size)}, got {scales.shape}"
        )
    if np.any(~np.isfinite(scales)) or np.any(scales <= 0):
        raise ValueError("length scales must be positive and finite")
    for axis in (query_xs, query_ys):
        if axis.ndim != 1 or not np.all(np.isfinite(axis)):
            raise ValueError("query axes must be finite 1-D arrays")
    blocks = []
    for value in np.unique(scales):
        gx = _gaussian_factor(query_xs[:, None] - hinge_xs[None, :], float(value))
        gy = _gaussian_factor(query_ys[:, None] - hinge_ys[None, :], float(value))
        blocks.append((gx, gy, (scales == value).astype(np.float64)))
    return blocks


def grid_predictive_moments(
    query_xs: FloatArray,
    query_ys: FloatArray,
    hinge_xs: FloatArray,
    hinge_ys: FloatArray,
    length_scales: FloatArray,
    belief: GaussianWeights,
    bias: bool,
) -> tuple[FloatArray, FloatArray]:
    """Activation mean and variance on the grid ``query_xs x query_ys``.

    Parameters
    ----------
    query_xs, query_ys : (qx,), (qy,) float64
    hinge_xs, hinge_ys : (nx,), (ny,) float64
    length_scales : (nx, ny) float64
    belief : GaussianWeights
        Over ``nx * ny`` hinge weights (x-major) followed by the bias weight if ``bias``.
    bias : bool

    Returns
    -------
    mu, var : (qy, qx) float64
        Row ``b`` is ``y = query_ys[b]`` (image layout).
    """
    qx, qy = np.asarray(query_xs, float), np.asarray(query_ys, float)
    nx, ny = hinge_xs.size, hinge_ys.size
    m = nx * ny
    if belief.dimension != m + int(bias):
        raise ValueError(f"belief has {belief.dimension} weights, expected {m + int(bias)}")
    blocks = _axis_blocks(qx, qy, hinge_xs, hinge_ys, length_scales)
    mean_w = belief.mean[:m].reshape(nx, ny)
    mu = np.zeros((qx.size, qy.size))
    for gx, gy, mask in blocks:
        mu += gx @ (mean_w * mask) @ gy.T

    if belief.diagonal:
        cov_hh = np.diag(1.0 / np.diag(belief.precision))
    else:
        cov_hh = belief.covariance()
    tensor = cov_hh[:m, :m].reshape(nx, ny, nx, ny)
    var = np.zeros((qx.size, qy.size))
    # Query columns at once: bounds the (columns, ny, nx, ny) and (columns, ny, qy) blocks
    # to about 2 M doubles each (a tiled map's 24 x 24 hinges at 2.5 mm would take 80 MB).
    step = max(1, min(_ENTRIES // max(1, ny * m), _ENTRIES // max(1, ny * qy.size)))
    for p, (gx_p, gy_p, mask_p) in enumerate(blocks):
        for q in range(p, len(blocks)):
            gx_q, gy_q, mask_q = blocks[q]
            part = tensor
            if len(blocks) > 1:
                part = tensor * (mask_p[:, :, None, None] * mask_q[None, None, :, :])
            for start in range(0, qx.size, step):
                a = slice(start, start + step)
                # Contract the two x-axes first (a: query x), then the two y-axes (b: query
                # y), with BLAS products: u[a, j, k, m] = sum_i gx_p[a, i] S[i, j, k, m].
                u = np.tensordot(gx_p[a], part, axes=(1, 0))  # (qx, ny, nx, ny)
                # v[a, j, m] = sum_k u[a, j, k, m] gx_q[a, k]: a batched matrix-vector product.
                v = np.matmul(u.transpose(0, 1, 3, 2), gx_q[a, None, :, None])[..., 0]
                w = v @ gy_q.T  # (qx, ny, qy): w[a, j, b] = sum_m v[a, j, m] gy_q[b, m]
                term = np.sum(w * gy_p.T[None, :, :], axis=1)  # sum_j gy_p[b, j] w[a, j, b]
                # S is symmetric, so the (q, p) term equals the (p, q) term.
                var[a] += term if q == p else 2.0 * term
    if bias:
        cross = cov_hh[:m, m].reshape(nx, ny)
        for gx, gy, mask in blocks:
            var += 2.0 * (gx @ (cross * mask) @ gy.T)
        var += cov_hh[m, m]
        mu += belief.mean[m]
    return mu.T.copy(), np.maximum(var, 0.0).T.copy()


def grid_activation_samples(
    query_xs: FloatArray,
    query_ys: FloatArray,
    hinge_xs: FloatArray,
    hinge_ys: FloatArray,
    length_scales: FloatArray,
    weight_samples: FloatArray,
    bias: bool,
) -> FloatArray:
    """Activations of every grid point under ``K`` weight samples.

    Parameters
    ----------
    weight_samples : (D, K) float64
        Columns are weight vectors (hinges x-major, then the bias weight if ``bias``).

    Returns
    -------
    (qy, qx, K) float64
    """
    qx, qy = np.asarray(query_xs, float), np.asarray(query_ys, float)
    nx, ny = hinge_xs.size, hinge_ys.size
    m = nx * ny
    samples = np.asarray(weight_samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[0] != m + int(bias):
        raise ValueError(f"weight_samples must have {m + int(bias)} rows, got {samples.shape}")
    count = samples.shape[1]
    hinge_samples = samples[:m].reshape(nx, ny, count)
    out = np.zeros((qy.size, qx.size, count))
    blocks = _axis_blocks(qx, qy, hinge_xs, hinge_ys, length_scales)
    for gx, gy, mask in blocks:
        # Contract the hinge x-axis, then the hinge y-axis (BLAS through tensordot).
        masked = hinge_samples if len(blocks) == 1 else hinge_samples * mask[:, :, None]
        along_x = np.tensordot(gx, masked, axes=(1, 0))  # (qx, ny, K)
        out += np.tensordot(gy, along_x, axes=(1, 1))  # (qy, qx, K)
    if bias:
        out += samples[m][None, None, :]
    return out
