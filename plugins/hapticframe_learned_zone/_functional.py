"""The learned zone's numpy layer: pure array functions, no state (issue 32 §2).

The model is a table over a grid of cells fixed to the plate (``ahead`` along the direction
of motion, ``aside`` to its left), per depth band and per class the classifier reports:
how often each class was reported while the cell held the object, and while it did not.
From those counts come the likelihoods p(class | cell occupied) and p(class | cell free)
(Dirichlet posteriors shrunk towards coarser evidence, so that a cell the calibration
rarely saw occupied says nothing rather than something wrong) and the log likelihood ratio
a report carries about each cell.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "cell_offsets",
    "count_reports",
    "depth_band",
    "inside_outlines",
    "likelihood_tables",
    "log_ratio",
    "observation_weights",
    "onset_window",
    "place",
    "survival_background",
    "travel_thinning",
]

FloatArray = NDArray[np.float64]


def cell_offsets(ahead_m: ArrayLike, aside_m: ArrayLike) -> FloatArray:
    """``(len(ahead) * len(aside), 2)`` plate-frame offsets, ahead-major."""
    a = np.asarray(ahead_m, dtype=np.float64).reshape(-1)
    s = np.asarray(aside_m, dtype=np.float64).reshape(-1)
    grid_a, grid_s = np.meshgrid(a, s, indexing="ij")
    return np.column_stack([grid_a.ravel(), grid_s.ravel()])


def place(offsets_m: ArrayLike, positions_m: ArrayLike, headings_rad: ArrayLike) -> FloatArray:
    """``(n, c, 2)`` map-frame points of plate-frame ``offsets`` at each of ``n`` poses."""
    o = np.asarray(offsets_m, dtype=np.float64).reshape(-1, 2)
    p = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    h = np.asarray(headings_rad, dtype=np.float64).reshape(-1)
    c, s = np.cos(h)[:, None], np.sin(h)[:, None]
    x = p[:, 0:1] + c * o[None, :, 0] - s * o[None, :, 1]
    y = p[:, 1:2] + s * o[None, :, 0] + c * o[None, :, 1]
    return np.stack([x, y], axis=-1)


def inside_outlines(points_m: ArrayLike, outlines: Sequence[ArrayLike]) -> NDArray[np.bool_]:
    """Which points lie inside any closed outline (even-odd rule; vertices closed last to
    first). Any leading shape of ``points_m`` (..., 2) is kept."""
    p = np.asarray(points_m, dtype=np.float64)
    shape = p.shape[:-1]
    flat = p.reshape(-1, 2)
    hit = np.zeros(len(flat), dtype=bool)
    for outline in outlines:
        v = np.asarray(outline, dtype=np.float64).reshape(-1, 2)
        odd = np.zeros(len(flat), dtype=bool)
        # One edge at a time over all points: the memory stays that of the points.
        for (x0, y0), (x1, y1) in zip(v, np.roll(v, -1, axis=0), strict=True):
            if y0 == y1:
                continue
            straddles = (flat[:, 1] >= min(y0, y1)) & (flat[:, 1] < max(y0, y1))
            x_cross = x0 + (flat[:, 1] - y0) * (x1 - x0) / (y1 - y0)
            odd ^= straddles & (flat[:, 0] < x_cross)
        hit |= odd
    return hit.reshape(shape)


def travel_thinning(positions_m: ArrayLike, movement_index: ArrayLike, spacing_m: float
                    ) -> NDArray[np.bool_]:
    """Samples kept when one is kept per ``spacing_m`` of path length within each movement
    (the first of each movement always), so that a slow or halted plate does not weigh more."""
    p = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    m = np.asarray(movement_index).reshape(-1)
    keep = np.zeros(len(p), dtype=bool)
    if not len(p):
        return keep
    step = np.r_[0.0, np.hypot(*np.diff(p, axis=0).T)]
    starts = np.r_[True, m[1:] != m[:-1]]
    step[starts] = 0.0
    travel = np.cumsum(step)
    base = np.maximum.accumulate(np.where(starts, travel, -np.inf))
    bucket = np.floor((travel - base) / spacing_m) if spacing_m > 0 else np.arange(len(p))
    keep[0] = True
    keep[1:] = starts[1:] | (bucket[1:] != bucket[:-1])
    return keep


def onset_window(positions_m: ArrayLike, movement_index: ArrayLike, labels: ArrayLike,
                 after_m: float) -> NDArray[np.bool_]:
    """Samples a halting search would have seen: in each movement, those up to ``after_m``
    of travel past its first report of a class other than the first (the background class,
    ``free``); all of a movement that never reported one.

    A search halts a movement at that first report, so what the plate felt while raking on
    through the object (the calibration's ``halt_on_interaction: false``) is not what a
    search's reports mean.
    """
    p = np.asarray(positions_m, dtype=np.float64).reshape(-1, 2)
    m = np.asarray(movement_index).reshape(-1)
    lab = np.asarray(labels).reshape(-1)
    keep = np.ones(len(p), dtype=bool)
    if not len(p):
        return keep
    step = np.r_[0.0, np.hypot(*np.diff(p, axis=0).T)]
    bounds = np.flatnonzero(np.r_[True, m[1:] != m[:-1], True])
    for lo, hi in pairwise(bounds.tolist()):
        hits = np.flatnonzero(lab[lo:hi] != 0)
        if hits.size:
            travel = np.cumsum(np.r_[0.0, step[lo + 1:hi]])
            keep[lo:hi] = travel <= travel[hits[0]] + after_m
    return keep


def depth_band(depth_m: ArrayLike, edges_m: ArrayLike) -> NDArray[np.intp]:
    """Depth band of each depth (0 .. len(edges)); -1 where the depth is not finite."""
    d = np.asarray(depth_m, dtype=np.float64).reshape(-1)
    band = np.searchsorted(np.asarray(edges_m, dtype=np.float64), d, side="right")
    return np.where(np.isfinite(d), band, -1).astype(np.intp)


def count_reports(occupied: NDArray[np.bool_], probabilities: ArrayLike, band: ArrayLike,
                  n_bands: int) -> tuple[FloatArray, FloatArray]:
    """Soft counts ``(bands, cells, classes)`` of each class reported while each cell held
    the object (first) and while it did not (second); samples of band -1 count nowhere.

    ``occupied`` is ``(n, cells)``; ``probabilities`` ``(n, classes)``.
    """
    occ = np.asarray(occupied, dtype=np.float64)
    q = np.asarray(probabilities, dtype=np.float64)
    b = np.asarray(band).reshape(-1)
    k = q.shape[1]
    n_occ = np.zeros((n_bands, occ.shape[1], k))
    n_free = np.zeros((n_bands, occ.shape[1], k))
    for i in range(n_bands):
        rows = b == i
        if rows.any():
            n_occ[i] = occ[rows].T @ q[rows]
            n_free[i] = (1.0 - occ[rows]).T @ q[rows]
    return n_occ, n_free


def _shrunk(counts: FloatArray, prior: FloatArray, strength: float) -> FloatArray:
    """Dirichlet posterior mean over the last axis, ``strength`` pseudo-counts at ``prior``."""
    mean: FloatArray = (counts + strength * prior) / (
        counts.sum(axis=-1, keepdims=True) + strength)
    return mean


def likelihood_tables(n_occ: ArrayLike, n_free: ArrayLike, marginal: ArrayLike,
                      strength: float, depth_strength: float | None = None
                      ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """p(class | cell occupied), p(class | cell free) and the samples with the cell occupied.

    Inputs are ``(bands, cells, classes)`` counts and the class frequencies of every
    counted sample. Returns ``(bands + 1, cells, classes)`` twice and ``(bands + 1,
    cells)``: the last band pools every depth (used where the depth is unknown). Each
    likelihood is a Dirichlet posterior mean: pooled over depths at ``strength``
    pseudo-counts towards ``marginal``, a band's towards the pooled one at
    ``depth_strength`` (default ``strength``). A cell that was rarely occupied in the
    calibration thus reports with the class frequencies whether occupied or free: a
    likelihood ratio near 1, which says nothing, rather than a ratio of two tiny rates.
    """
    occ = np.asarray(n_occ, dtype=np.float64)
    free = np.asarray(n_free, dtype=np.float64)
    pi = np.asarray(marginal, dtype=np.float64).reshape(1, -1)
    band_strength = strength if depth_strength is None else depth_strength
    pooled_occ = _shrunk(occ.sum(axis=0), pi, strength)
    pooled_free = _shrunk(free.sum(axis=0), pi, strength)
    band_occ = _shrunk(occ, pooled_occ[None], band_strength)
    band_free = _shrunk(free, pooled_free[None], band_strength)
    occupied = occ.sum(axis=2)
    return (np.concatenate([band_occ, pooled_occ[None]]),
            np.concatenate([band_free, pooled_free[None]]),
            np.concatenate([occupied, occupied.sum(axis=0)[None]]))


def log_ratio(p_occ: FloatArray, p_free: FloatArray, probabilities: ArrayLike) -> FloatArray:
    """log p(report | occupied) − log p(report | free) per cell for one soft report
    (``p_occ``, ``p_free``: ``(cells, classes)``; the report's likelihood is the mixture
    over classes weighted by its probabilities). Finite: the prior keeps both positive."""
    q = np.asarray(probabilities, dtype=np.float64).reshape(-1)
    tiny = np.finfo(np.float64).tiny
    result: FloatArray = (np.log(np.maximum(p_occ @ q, tiny))
                          - np.log(np.maximum(p_free @ q, tiny)))
    return result


def observation_weights(odds_change: FloatArray, samples: FloatArray, strength: float,
                        full_weight_change: float) -> FloatArray:
    """Confidence of each cell's target: how far the report moves the cell's log odds (its
    log likelihood ratio, relative to ``full_weight_change``, capped at 1), times the share
    of the likelihood that the samples with the cell occupied carry rather than the prior,
    n / (n + strength)."""
    size = np.minimum(np.abs(odds_change) / full_weight_change, 1.0)
    weights: FloatArray = size * samples / (samples + strength)
    return weights


def survival_background(n_occ: ArrayLike, p_free_cell: ArrayLike, marginal: float,
                        strength: float, shape: tuple[int, int]
                        ) -> tuple[FloatArray, FloatArray]:
    """The background class's log likelihood ratio per cell, estimated as a survival.

    A search halts at its first report of another class, so the calibration rarely saw
    the cells nearest the plate (and never those it had passed) occupied: shrunk towards
    the class frequencies, their p(background | occupied) stays near the frequency of
    the background and a background report says little about them, although an object
    there would have been felt at least as surely as one farther ahead. Here, along each
    column of the grid (``shape`` = (ahead, aside), ahead-major cells, ``ahead`` rising),
    p(background | occupied) is shrunk, from the farthest cell towards the plate, towards
    the estimate of the next cell farther ahead (the farthest towards ``marginal``), and
    kept at most that: it does not rise as the object nears, and a cell seen rarely
    takes the evidence of the nearest cell farther ahead that was seen. ``n_occ`` are the
    depth-pooled counts ``(cells, classes)`` with the cell occupied, class 0 the
    background; ``p_free_cell`` the depth-pooled p(background | cell free) per cell.

    Returns
    -------
    ratio : ndarray, (cells,)
        log p(background | occupied) − log p(background | free), at most 0.
    samples : ndarray, (cells,)
        The occupied samples the estimate leans on: the most of the cell and of the cells
        farther ahead in its column.
    """
    occ = np.asarray(n_occ, dtype=np.float64)
    n_ahead, n_aside = shape
    total = occ.sum(axis=-1).reshape(n_ahead, n_aside)
    background = occ[:, 0].reshape(n_ahead, n_aside)
    free_rate = np.asarray(p_free_cell, dtype=np.float64).reshape(n_ahead, n_aside)
    estimate = np.empty((n_ahead, n_aside))
    samples = np.empty((n_ahead, n_aside))
    prior = np.full(n_aside, float(marginal))
    prior_samples = np.zeros(n_aside)
    for i in range(n_ahead - 1, -1, -1):
        estimate[i] = np.minimum((background[i] + strength * prior) / (total[i] + strength),
                                 prior)
        samples[i] = np.maximum(total[i], prior_samples)
        prior = estimate[i]
        prior_samples = samples[i]
    tiny = np.finfo(np.float64).tiny
    ratio = np.minimum(np.log(np.maximum(estimate, tiny)) - np.log(np.maximum(free_rate, tiny)),
                       0.0)
    return ratio.ravel(), samples.ravel()
