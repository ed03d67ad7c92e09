"""Array functions of the belief map: contact targets, bounded spatial binning, priors.

Pure numpy; no scikit-learn here (the classifier is fitted in :mod:`._belief_map`).

Binning
-------
Observations are summarised per (cell, decided class): the summed weight and the
weight-weighted sum of positions. Keys are cell indices ``floor(x / cell)`` kept as float64,
so coordinates of any finite size give finite keys. Doubling the cell size maps a key ``k``
to ``floor(k / 2)`` exactly (``floor(floor(x / c) / 2) == floor(x / (2 c))``), so merging
bins after coarsening gives the same bins as binning the raw points at the coarser size;
the number of occupied bins can only grow as data arrive, so the level reached by streaming
updates equals the level a single fit of the union reaches.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "Bins",
    "bernoulli_std",
    "bin_observations",
    "bound_bins",
    "coarsen_bins",
    "contact_targets",
    "extent_region",
    "merge_bins",
    "smoothed_fraction",
    "support_weight",
]

FloatArray = NDArray[np.float64]


def contact_targets(
    probabilities: FloatArray,
    classes: Sequence[str],
    contact_class: str,
    class_targets: Mapping[str, float] | None = None,
) -> FloatArray:
    """Occupancy target per row: the contact probability, or a class-weighted sum.

    Parameters
    ----------
    probabilities : (n, k) float64
        Class probabilities, rows summing to 1.
    classes : sequence of str
        The k class names.
    contact_class : str
        Used when ``class_targets`` is None: the target is that class's probability.
    class_targets : mapping of str to float, optional
        Target value per class name (others count 0); the target is ``sum_k p_k v_k``.

    Raises
    ------
    ValueError
        When a named class is not among ``classes``.
    """
    p = np.asarray(probabilities, dtype=np.float64)
    names = list(classes)
    values = np.zeros(len(names))
    mapping = {contact_class: 1.0} if class_targets is None else dict(class_targets)
    known = [name for name in mapping if name in names]
    if not known:
        raise ValueError(
            f"none of the classes {sorted(mapping)} is produced by the classifier (classes: "
            f"{names}); set contact_class or class_targets of the contact-point sensor model"
        )
    for name in known:
        values[names.index(name)] = mapping[name]
    if p.shape[0] == 0:
        return np.empty(0)
    # Rows sum to one, so the clip only removes rounding outside [0, 1].
    return np.clip(p @ values, 0.0, 1.0)


@dataclass(frozen=True)
class Bins:
    """Per (cell, class) summaries, sorted by key.

    Attributes
    ----------
    keys : (m, 3) float64
        Cell index along x, along y, and the decided class (0 free, 1 contact).
    weights : (m,) float64
        Summed observation weight (positive).
    position_sums : (m, 2) float64
        Sum of weight * position.
    """

    keys: FloatArray
    weights: FloatArray
    position_sums: FloatArray

    def __len__(self) -> int:
        return int(self.weights.size)

    @classmethod
    def empty(cls) -> Bins:
        return cls(np.empty((0, 3)), np.empty(0), np.empty((0, 2)))

    @property
    def positions(self) -> FloatArray:
        """Weighted mean position of each bin."""
        return self.position_sums / self.weights[:, None]

    @property
    def labels(self) -> NDArray[np.int64]:
        return self.keys[:, 2].astype(np.int64)


def _aggregate(keys: FloatArray, weights: FloatArray, position_sums: FloatArray) -> Bins:
    if keys.shape[0] == 0:
        return Bins.empty()
    # Sort rows lexicographically (x cell, y cell, class) and number the runs of equal rows;
    # np.unique(axis=0) does the same through a much slower structured-dtype sort.
    order = np.lexsort((keys[:, 2], keys[:, 1], keys[:, 0]))
    ordered = keys[order]
    starts = np.empty(len(ordered), dtype=bool)
    starts[0] = True
    np.any(ordered[1:] != ordered[:-1], axis=1, out=starts[1:])
    run = np.cumsum(starts) - 1
    inverse = np.empty(len(keys), dtype=np.intp)
    inverse[order] = run
    unique = ordered[starts]
    m = unique.shape[0]
    # Weighted bincounts are float64 already (numpy's stub says intp): astype copies nothing.
    summed_w = np.bincount(inverse, weights=weights, minlength=m).astype(np.float64, copy=False)
    sums = np.column_stack([
        np.bincount(inverse, weights=position_sums[:, 0], minlength=m),
        np.bincount(inverse, weights=position_sums[:, 1], minlength=m),
    ]).astype(np.float64, copy=False)
    return Bins(unique, summed_w, sums)


def bin_observations(
    points_m: FloatArray, targets: FloatArray, weights: FloatArray, cell_size_m: float
) -> Bins:
    """Bin observations by cell and decided class (target > 0.5 is contact).

    Observations with zero weight carry no information and are dropped.
    """
    w = np.asarray(weights, dtype=np.float64)
    keep = w > 0
    pts = np.asarray(points_m, dtype=np.float64)[keep]
    w = w[keep]
    decided = (np.asarray(targets, dtype=np.float64)[keep] > 0.5).astype(np.float64)
    with np.errstate(over="ignore"):
        cells = np.floor(pts / cell_size_m)
    cells = np.nan_to_num(cells, posinf=np.finfo(np.float64).max, neginf=-np.finfo(np.float64).max)
    keys = np.column_stack([cells, decided])
    return _aggregate(keys, w, pts * w[:, None])


def merge_bins(first: Bins, second: Bins) -> Bins:
    """Bins of the union of two binned sets at the same cell size."""
    if not len(first):
        return second
    if not len(second):
        return first
    return _aggregate(
        np.vstack([first.keys, second.keys]),
        np.concatenate([first.weights, second.weights]),
        np.vstack([first.position_sums, second.position_sums]),
    )


def coarsen_bins(bins: Bins) -> Bins:
    """Merge bins into cells of twice the edge length."""
    keys = bins.keys.copy()
    keys[:, :2] = np.floor(keys[:, :2] / 2.0)
    return _aggregate(keys, bins.weights, bins.position_sums)


def bound_bins(bins: Bins, level: int, max_points: int) -> tuple[Bins, int]:
    """Coarsen until at most ``max_points`` bins remain; return the bins and the new level.

    ``level`` counts doublings of the base cell size. At most two bins (one per class) are
    left once every point shares one cell, so ``max_points >= 2`` always terminates.
    """
    if max_points < 2:
        raise ValueError("max_points must be at least 2")
    while len(bins) > max_points:
        coarser = coarsen_bins(bins)
        level += 1
        if len(coarser) == len(bins) and np.array_equal(coarser.keys, bins.keys):
            # Keys at the float64 limit stop changing; nothing more can merge.
            raise ValueError("observations are spread too widely to bin (coordinates near 1e308)")
        bins = coarser
    return bins, level


def smoothed_fraction(contact_weight: float, total_weight: float) -> float:
    """Laplace-smoothed contact fraction ``(w_contact + 1) / (w_total + 2)``: 0.5 with no data."""
    return float((contact_weight + 1.0) / (total_weight + 2.0))


def bernoulli_std(mean: FloatArray) -> FloatArray:
    """``sqrt(p (1 - p))``: the spread of a Bernoulli variable, not a posterior std."""
    p = np.clip(np.asarray(mean, dtype=np.float64), 0.0, 1.0)
    return np.sqrt(p * (1.0 - p))


def extent_region(
    lower: FloatArray, upper: FloatArray, margin_m: float
) -> tuple[float, float, float, float]:
    """``(x_min, x_max, y_min, y_max)`` of the extent plus a margin, never of zero size."""
    pad = max(margin_m, 1e-3)
    return (
        float(lower[0] - pad),
        float(upper[0] + pad),
        float(lower[1] - pad),
        float(upper[1] + pad),
    )


def support_weight(
    points_m: FloatArray, representatives_m: FloatArray, length_scale_m: float, cell_size_m: float
) -> FloatArray:
    """RBF kernel value to the nearest bin: 1 on observed ground, 0 far from it.

    ``exp(-d^2 / (2 l^2))``, the kernel of the SVC (Eq. A.9), with ``d`` the distance to the
    nearest bin's mean position less the cell's half diagonal: a bin stands for observations
    anywhere in its cell, so ground within one cell of a bin counts as observed.
    """
    q = np.asarray(points_m, dtype=np.float64)
    if representatives_m.shape[0] == 0:
        return np.zeros(q.shape[0])
    from scipy.spatial import cKDTree

    distance, _ = cKDTree(representatives_m).query(q, k=1)
    beyond = np.maximum(np.asarray(distance) - cell_size_m / np.sqrt(2.0), 0.0)
    return np.exp(-0.5 * (beyond / length_scale_m) ** 2)
