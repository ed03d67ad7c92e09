"""Hinge features as rows over a feature matrix, dense or windowed (pure numpy).

The variational update (:func:`hapticframe_bhm._functional.variational_update`) touches the
features of a batch only through four reductions over its rows ``phi_n``:

- ``gram(c) = sum_n c_n phi_n phi_n^T`` (the precision increment),
- ``weighted_sum(v) = sum_n v_n phi_n`` (the shift increment),
- ``dot(m)_n = phi_n^T m`` (activation means),
- ``quadratic(S)_n = phi_n^T S phi_n`` (activation variances).

:class:`DenseRows` computes them from an ``(n, D)`` matrix with BLAS. :class:`WindowedRows`
uses that an RBF hinge feature is negligible beyond a few length scales: each point keeps
only the ``K x K`` hinges around it (features dropped are below ``TRUNCATION``, 1e-6), and
points are grouped by the window they share, so every reduction costs ``O(n K^2)`` or
``O(groups K^4)`` instead of ``O(n D^2)``. With 5 cm hinges and a 3 cm length scale a window
holds 49 of the 234 hinges of the thesis's 75 x 50 cm area.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["TRUNCATION", "DenseRows", "WindowedRows", "all_finite", "window_half_width"]

FloatArray = NDArray[np.float64]

#: Largest hinge feature a window may leave out.
TRUNCATION = 1e-6


def all_finite(array: FloatArray) -> bool:
    """True when every entry is finite.

    The sum is finite exactly when no entry is NaN or infinite, unless finite entries
    overflow it; only then are the entries tested one by one. One pass, no temporary mask.
    """
    if math.isfinite(float(np.sum(array))):
        return True
    return bool(np.all(np.isfinite(array)))


def window_half_width(length_scale_m: float, spacing_m: float) -> int:
    """Hinges kept on each side of the nearest one so that every feature left out is below
    :data:`TRUNCATION`.

    A hinge ``w + 1`` steps from the nearest hinge lies at least ``(w + 1/2)`` spacings from
    the point, where its (per-axis) factor is ``exp(-((w + 1/2) h / l)^2 / 2)``.
    """
    if not (length_scale_m > 0 and spacing_m > 0):
        raise ValueError("length scale and spacing must be positive")
    reach = math.sqrt(-2.0 * math.log(TRUNCATION)) * length_scale_m / spacing_m
    return max(0, math.ceil(reach - 0.5))


class DenseRows:
    """The four reductions over a dense ``(n, D)`` feature matrix."""

    def __init__(self, features: FloatArray) -> None:
        self.matrix = np.asarray(features, dtype=np.float64)
        if self.matrix.ndim != 2:
            raise ValueError("features must be a 2-D array")

    @property
    def count(self) -> int:
        return int(self.matrix.shape[0])

    @property
    def dimension(self) -> int:
        return int(self.matrix.shape[1])

    def all_finite(self) -> bool:
        return all_finite(self.matrix)

    def gram(self, curvature: FloatArray) -> FloatArray:
        scaled = self.matrix * np.sqrt(curvature)[:, None]
        return scaled.T @ scaled

    def weighted_sum(self, values: FloatArray) -> FloatArray:
        return self.matrix.T @ values

    def dot(self, vector: FloatArray) -> FloatArray:
        return self.matrix @ vector

    def quadratic(self, matrix: FloatArray) -> FloatArray:
        product = self.matrix @ matrix
        product *= self.matrix
        return product.sum(axis=1)

    def quadratic_diagonal(self, diagonal: FloatArray) -> FloatArray:
        return (self.matrix * self.matrix) @ diagonal


class WindowedRows:
    """Hinge features of ``points`` on a regular hinge grid, truncated to windows.

    Parameters
    ----------
    points : (n, 2) float64
        Finite points.
    xs, ys : (nx,), (ny,) float64
        Evenly spaced hinge axes (hinge ``i * ny + j`` is ``(xs[i], ys[j])``).
    length_scale : float
        One kernel length scale for every hinge.
    bias : bool
        A constant feature follows the hinge features.
    half_width : int
        Hinges kept on each side of the nearest one (see :func:`window_half_width`); the
        window has ``K = 2 half_width + 1`` hinges per axis and must fit in the grid.
    """

    def __init__(
        self,
        points: FloatArray,
        xs: FloatArray,
        ys: FloatArray,
        length_scale: float,
        bias: bool,
        half_width: int,
    ) -> None:
        p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
        self.nx, self.ny = int(xs.size), int(ys.size)
        self.k = 2 * int(half_width) + 1
        if self.k > min(self.nx, self.ny):
            raise ValueError("the window does not fit in the hinge grid")
        self.bias = bool(bias)
        self._hinges = self.nx * self.ny
        n = p.shape[0]
        offsets = np.arange(self.k)
        corners = []
        factors = []
        for axis, hinges, size in ((0, xs, self.nx), (1, ys, self.ny)):
            step = float(hinges[1] - hinges[0])
            nearest = np.rint((p[:, axis] - hinges[0]) / step)
            # Clip in floating point first: far-away points must not overflow the int cast.
            start = np.clip(nearest - half_width, 0, size - self.k).astype(np.intp)
            window = hinges[start[:, None] + offsets[None, :]]
            gaps = (window - p[:, axis : axis + 1]) / length_scale
            with np.errstate(under="ignore"):
                factors.append(np.exp(-0.5 * np.minimum(gaps * gaps, 1e4)))
            corners.append(start)
        cell = corners[0] * self.ny + corners[1]
        self.order = np.argsort(cell, kind="stable")
        sorted_cells = cell[self.order]
        if n:
            first = np.flatnonzero(np.r_[True, sorted_cells[1:] != sorted_cells[:-1]])
        else:
            first = np.empty(0, np.intp)
        self.starts = first
        self.stops = np.r_[first[1:], n].astype(np.intp) if n else np.empty(0, np.intp)
        self.corner_x = corners[0][self.order][first] if n else np.empty(0, np.intp)
        self.corner_y = corners[1][self.order][first] if n else np.empty(0, np.intp)
        gx, gy = factors[0][self.order], factors[1][self.order]
        # Rows in window order (x-major within the window, like the hinges).
        self.rows = (gx[:, :, None] * gy[:, None, :]).reshape(n, self.k * self.k)
        # Flat hinge index of every window entry, per group: (groups, K*K).
        window = (offsets[:, None] * self.ny + offsets[None, :]).ravel()
        self.columns = (self.corner_x * self.ny + self.corner_y)[:, None] + window[None, :]
        self.group = np.repeat(np.arange(first.size), self.stops - self.starts)

    @property
    def count(self) -> int:
        return int(self.rows.shape[0])

    @property
    def dimension(self) -> int:
        return self._hinges + int(self.bias)

    def all_finite(self) -> bool:
        return all_finite(self.rows)

    def _unsort(self, values: FloatArray) -> FloatArray:
        out = np.empty_like(values)
        out[self.order] = values
        return out

    def gram(self, curvature: FloatArray) -> FloatArray:
        """``sum_n c_n phi_n phi_n^T`` as a dense ``(D, D)`` matrix."""
        c = np.asarray(curvature, dtype=np.float64)[self.order]
        nx, ny, k = self.nx, self.ny, self.k
        block = np.zeros((nx, ny, nx, ny))
        scaled = self.rows * np.sqrt(c)[:, None]
        for g, (a, b) in enumerate(zip(self.starts, self.stops, strict=True)):
            rows = scaled[a:b]
            i, j = self.corner_x[g], self.corner_y[g]
            block[i : i + k, j : j + k, i : i + k, j : j + k] += (rows.T @ rows).reshape(k, k, k, k)
        out = np.zeros((self.dimension, self.dimension))
        out[: self._hinges, : self._hinges] = block.reshape(self._hinges, self._hinges)
        if self.bias:
            cross = self._scatter(np.add.reduceat(self.rows * c[:, None], self.starts, axis=0)
                                  if self.count else np.zeros((0, k * k)))
            out[: self._hinges, -1] = cross
            out[-1, : self._hinges] = cross
            out[-1, -1] = float(c.sum())
        return out

    def _scatter(self, per_group: FloatArray) -> FloatArray:
        """Sum ``(groups, K*K)`` window values into a hinge vector."""
        return np.bincount(
            self.columns.ravel(), weights=per_group.ravel(), minlength=self._hinges
        ).astype(np.float64)

    def weighted_sum(self, values: FloatArray) -> FloatArray:
        """``sum_n v_n phi_n``."""
        v = np.asarray(values, dtype=np.float64)[self.order]
        out = np.zeros(self.dimension)
        if self.count:
            out[: self._hinges] = self._scatter(
                np.add.reduceat(self.rows * v[:, None], self.starts, axis=0)
            )
        if self.bias:
            out[-1] = float(v.sum())
        return out

    def dot(self, vector: FloatArray) -> FloatArray:
        """``phi_n^T m`` for every row."""
        m = np.asarray(vector, dtype=np.float64)
        local = m[: self._hinges][self.columns][self.group]  # (n, K*K)
        out = np.einsum("ij,ij->i", self.rows, local)
        if self.bias:
            out = out + m[-1]
        return self._unsort(out)

    def quadratic(self, matrix: FloatArray) -> FloatArray:
        """``phi_n^T S phi_n`` for every row, with ``S`` symmetric ``(D, D)``."""
        s = np.asarray(matrix, dtype=np.float64)
        nx, ny, k = self.nx, self.ny, self.k
        # A contiguous (nx, ny, nx, ny) copy: each window block is then a plain slice.
        block = np.ascontiguousarray(s[: self._hinges, : self._hinges]).reshape(nx, ny, nx, ny)
        out = np.empty(self.count)
        for g, (a, b) in enumerate(zip(self.starts, self.stops, strict=True)):
            i, j = self.corner_x[g], self.corner_y[g]
            local = block[i : i + k, j : j + k, i : i + k, j : j + k].reshape(k * k, k * k)
            rows = self.rows[a:b]
            out[a:b] = np.sum((rows @ local) * rows, axis=1)
        if self.bias:
            cross = s[: self._hinges, -1][self.columns][self.group]
            out += 2.0 * np.einsum("ij,ij->i", self.rows, cross) + s[-1, -1]
        return self._unsort(out)

    def quadratic_diagonal(self, diagonal: FloatArray) -> FloatArray:
        """``phi_n^T diag(d) phi_n`` for every row."""
        d = np.asarray(diagonal, dtype=np.float64)
        local = d[: self._hinges][self.columns][self.group]
        out = np.einsum("ij,ij->i", self.rows * self.rows, local)
        if self.bias:
            out = out + d[-1]
        return self._unsort(out)
