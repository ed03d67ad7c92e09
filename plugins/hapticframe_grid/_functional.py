"""Log-odds occupancy grid numerics as pure array functions (numpy/scipy only).

A cell holds the log odds ``L = log(p / (1 - p))`` of being occupied, 0 (p = 0.5) when
unknown. An observation with soft target ``y`` in [0, 1] and weight ``w`` adds
``w (2y - 1) logit(p_hit)`` to its cell when ``y >= 0.5`` and ``w (1 - 2y) logit(p_miss)``
when ``y < 0.5``: a hard hit or miss is OctoMap's update, and ``y = 0.5`` says nothing. (The
linear mix ``y l_hit + (1 - y) l_miss`` would turn "unknown" into evidence of occupancy,
because OctoMap's hit and miss constants are asymmetric.) The cell is then clamped
to ``[logit(p_min), logit(p_max)]`` as in OctoMap's ``updateNodeLogOdds``. Observations are
applied one at a time in their given order, so fusing two batches one after the other
equals fusing their concatenation exactly (clamping makes the order matter within a cell).
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import expit

__all__ = [
    "cell_indices",
    "fuse_clamped",
    "grid_shape",
    "observation_increments",
    "occupancy_probability",
    "occupancy_std",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]


def grid_shape(width_m: float, height_m: float, cell_size_m: float) -> tuple[int, int]:
    """Cells along x and y needed to cover a ``width x height`` rectangle (at least 1 each)."""
    if not (cell_size_m > 0 and np.isfinite(cell_size_m)):
        raise ValueError(f"cell size must be positive and finite, got {cell_size_m!r}")
    # The slack keeps 0.75 / 0.01 from rounding up to 76 cells.
    nx = max(1, int(np.ceil(width_m / cell_size_m - 1e-9)))
    ny = max(1, int(np.ceil(height_m / cell_size_m - 1e-9)))
    return nx, ny


def cell_indices(
    points_m: ArrayLike,
    origin_m: tuple[float, float],
    extent_m: tuple[float, float],
    cell_size_m: float,
    shape: tuple[int, int],
) -> tuple[IntArray, NDArray[np.bool_]]:
    """Flat cell index (x-major) of each point and whether the point lies in the region.

    Points on the far edges belong to the last cell; indices of points outside are 0 and
    must be ignored through the mask.
    """
    p = np.asarray(points_m, dtype=np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(p)):
        raise ValueError("points contain NaN or infinity")
    rel = p - np.asarray(origin_m, dtype=np.float64)
    inside_x = (rel[:, 0] >= 0) & (rel[:, 0] <= extent_m[0])
    inside = inside_x & (rel[:, 1] >= 0) & (rel[:, 1] <= extent_m[1])
    ix = np.clip(np.floor(rel[:, 0] / cell_size_m), 0, shape[0] - 1).astype(np.intp)
    iy = np.clip(np.floor(rel[:, 1] / cell_size_m), 0, shape[1] - 1).astype(np.intp)
    flat = np.where(inside, ix * shape[1] + iy, 0)
    return flat, inside


def observation_increments(
    targets: ArrayLike, weights: ArrayLike, log_odds_hit: float, log_odds_miss: float
) -> FloatArray:
    """Log-odds increment per observation: neutral at ``y = 0.5``, OctoMap's hit at 1, miss at 0."""
    y = np.asarray(targets, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    return w * np.where(y >= 0.5, (2.0 * y - 1.0) * log_odds_hit, (1.0 - 2.0 * y) * log_odds_miss)


def fuse_clamped(
    log_odds: FloatArray, cells: IntArray, increments: FloatArray, low: float, high: float
) -> None:
    """Add ``increments`` to ``log_odds[cells]`` one observation at a time, clamping each step.

    Updates ``log_odds`` (flat, float64) in place. Vectorised in rounds: round ``k`` applies
    the ``k``-th observation of every cell at once, which preserves the per-cell order.
    """
    cells = np.asarray(cells, dtype=np.intp)
    inc = np.asarray(increments, dtype=np.float64)
    if cells.shape != inc.shape:
        raise ValueError("cells and increments must have the same shape")
    if cells.size == 0:
        return
    order = np.argsort(cells, kind="stable")
    sorted_cells = cells[order]
    starts = np.flatnonzero(np.r_[True, sorted_cells[1:] != sorted_cells[:-1]])
    run_lengths = np.diff(np.r_[starts, sorted_cells.size])
    rank = np.arange(sorted_cells.size) - np.repeat(starts, run_lengths)
    # Group observations by their rank within their cell: each group touches distinct cells.
    by_rank = np.argsort(rank, kind="stable")
    observation = order[by_rank]
    bounds = np.searchsorted(rank[by_rank], np.arange(int(run_lengths.max()) + 1))
    for begin, end in itertools.pairwise(bounds):
        chosen = observation[begin:end]
        target = cells[chosen]
        log_odds[target] = np.clip(log_odds[target] + inc[chosen], low, high)


def occupancy_probability(log_odds: ArrayLike) -> FloatArray:
    """``expit(L)``."""
    return expit(np.asarray(log_odds, dtype=np.float64))


def occupancy_std(probability: ArrayLike) -> FloatArray:
    """Bernoulli standard deviation ``sqrt(p (1 - p))``."""
    p = np.asarray(probability, dtype=np.float64)
    return np.sqrt(np.clip(p * (1.0 - p), 0.0, 0.25))
