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

Calibration
-----------
Platt scaling (Eq. A.11) fits ``P = sigmoid(s f + c)`` to held-out SVC decision values
``f``. Two things keep it from inverting the map (issue 16):

- The held-out data are raw observations, not bins: each observation belongs to a fold by
  a hash of its position (:func:`observation_folds`), bins are kept per fold, and a fold's
  bins are scored by an SVC fitted on the other folds' (:func:`calibration_splits`). Bins
  dealt to folds would not do: a noisy coarse cell holds a free and a contact bin at nearly
  one position, and split across folds each is scored by its opposite-class twin, so the
  scores point the wrong way (3,000 scattered points, 6.4 cm cells: Platt's ``A`` was
  +8.8 and the map's AUC 0.04).
- The slope is bounded, ``s >= 0`` (:func:`platt_fit`): a higher decision value never
  lowers ``P``. Scores that rank the held-out data no better than chance give ``s = 0``, a
  flat map at the smoothed base rate, never an inverted one.
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
    "calibration_splits",
    "cell_folds",
    "coarsen_bins",
    "contact_targets",
    "extent_region",
    "merge_bins",
    "merge_folds",
    "observation_folds",
    "platt_fit",
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
    keys : (m, 4) float64
        Cell index along x, along y, the decided class (0 free, 1 contact) and the
        calibration fold of the observations (:func:`observation_folds`).
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
        return cls(np.empty((0, 4)), np.empty(0), np.empty((0, 2)))

    @property
    def positions(self) -> FloatArray:
        """Weighted mean position of each bin."""
        return self.position_sums / self.weights[:, None]

    @property
    def labels(self) -> NDArray[np.int64]:
        return self.keys[:, 2].astype(np.int64)

    @property
    def cells_and_classes(self) -> int:
        """Number of distinct (cell, class) pairs: the bins once folds are merged."""
        if not len(self):
            return 0
        # Rows are sorted by (x, y, class, fold), so equal (x, y, class) rows are adjacent.
        return 1 + int(np.any(self.keys[1:, :3] != self.keys[:-1, :3], axis=1).sum())

    def select(self, rows: NDArray[np.bool_]) -> Bins:
        """The bins where ``rows`` is True (still sorted)."""
        return Bins(self.keys[rows], self.weights[rows], self.position_sums[rows])


def _aggregate(keys: FloatArray, weights: FloatArray, position_sums: FloatArray) -> Bins:
    if keys.shape[0] == 0:
        return Bins.empty()
    # Sort rows lexicographically (x cell, y cell, class, fold) and number the runs of equal
    # rows; np.unique(axis=0) does the same through a much slower structured-dtype sort.
    order = np.lexsort(keys.T[::-1])
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


def observation_folds(points_m: FloatArray, folds: int) -> FloatArray:
    """Calibration fold ``0 .. folds - 1`` of each observation, from a hash of its position.

    A hash rather than the arrival index keeps the map independent of arrival order;
    coincident observations share a fold.
    """
    pts = np.ascontiguousarray(points_m, dtype=np.float64).reshape(-1, 2)
    bits = pts.view(np.uint64)
    # splitmix64's finaliser over both coordinates' bits (uint64 arithmetic wraps).
    h = (bits[:, 0] * np.uint64(0x9E3779B97F4A7C15)) ^ (bits[:, 1] * np.uint64(0xC2B2AE3D27D4EB4F))
    h ^= h >> np.uint64(30)
    h *= np.uint64(0xBF58476D1CE4E5B9)
    h ^= h >> np.uint64(27)
    h *= np.uint64(0x94D049BB133111EB)
    h ^= h >> np.uint64(31)
    return (h % np.uint64(folds)).astype(np.float64)


def bin_observations(
    points_m: FloatArray,
    targets: FloatArray,
    weights: FloatArray,
    cell_size_m: float,
    folds: int = 1,
) -> Bins:
    """Bin observations by cell, decided class (target > 0.5 is contact) and fold.

    Observations with zero weight carry no information and are dropped. ``folds`` is the
    number of calibration folds the observations are dealt to (:func:`observation_folds`).
    """
    w = np.asarray(weights, dtype=np.float64)
    keep = w > 0
    pts = np.asarray(points_m, dtype=np.float64)[keep]
    w = w[keep]
    decided = (np.asarray(targets, dtype=np.float64)[keep] > 0.5).astype(np.float64)
    with np.errstate(over="ignore"):
        cells = np.floor(pts / cell_size_m)
    cells = np.nan_to_num(cells, posinf=np.finfo(np.float64).max, neginf=-np.finfo(np.float64).max)
    keys = np.column_stack([cells, decided, observation_folds(pts, folds)])
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


def merge_folds(bins: Bins, exclude: float | None = None) -> Bins:
    """Bins of all folds (but ``exclude``) merged per (cell, class), with fold 0."""
    rows = np.ones(len(bins), dtype=bool) if exclude is None else bins.keys[:, 3] != exclude
    keys = bins.keys[rows].copy()
    keys[:, 3] = 0.0
    return _aggregate(keys, bins.weights[rows], bins.position_sums[rows])


def coarsen_bins(bins: Bins) -> Bins:
    """Merge bins into cells of twice the edge length."""
    keys = bins.keys.copy()
    keys[:, :2] = np.floor(keys[:, :2] / 2.0)
    return _aggregate(keys, bins.weights, bins.position_sums)


def bound_bins(bins: Bins, level: int, max_points: int) -> tuple[Bins, int]:
    """Coarsen until at most ``max_points`` (cell, class) pairs remain; return the bins and
    the new level.

    ``level`` counts doublings of the base cell size. Folds are not counted: a refit's SVCs
    are fitted on bins merged over folds. At most two pairs (one per class) are left once
    every point shares one cell, so ``max_points >= 2`` always terminates.
    """
    if max_points < 2:
        raise ValueError("max_points must be at least 2")
    while bins.cells_and_classes > max_points:
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


def cell_folds(keys: FloatArray, folds: int, seed: int) -> NDArray[np.intp]:
    """Cross-validation fold of each bin: whole cells per fold, both classes left to train on.

    Parameters
    ----------
    keys : (m, 3) or (m, 4) float64
        Keys of bins merged over folds (x cell, y cell, class[, fold]), as :attr:`Bins.keys`.
    folds : int
        Folds wanted; fewer are used when fewer cells hold a class (a cell holds at most one
        bin of each class, so ``min(folds, contact cells, free cells)``).
    seed : int
        Seeds the shuffle of cells, so the folds depend only on the bins (not their order).

    Returns
    -------
    (m,) intp
        Fold index per bin, ``0 .. k - 1``; every fold holds a contact bin, and every
        complement of a fold holds bins of both classes.

    Raises
    ------
    ValueError
        When fewer than two cells hold a bin of either class.
    """
    keys = np.asarray(keys, dtype=np.float64)
    labels = keys[:, 2] > 0.5
    cells, group = np.unique(keys[:, :2], axis=0, return_inverse=True)
    group = group.ravel()
    n_cells = cells.shape[0]
    has_contact = np.bincount(group, weights=labels, minlength=n_cells) > 0
    has_free = np.bincount(group, weights=~labels, minlength=n_cells) > 0
    k = min(int(folds), int(has_contact.sum()), int(has_free.sum()))
    if k < 2:
        raise ValueError(
            "cross-validated calibration needs at least two cells with contact and two without "
            f"(got {int(has_contact.sum())} and {int(has_free.sum())})"
        )
    order = np.random.default_rng(seed).permutation(n_cells)
    fold_of_cell = np.full(n_cells, -1, dtype=np.intp)
    # Cells with contact are dealt round robin, those with both classes first: every fold
    # then holds contact, and so does every complement (at least two folds have some).
    contact_cells = order[has_contact[order]]
    contact_cells = contact_cells[np.argsort(~has_free[contact_cells], kind="stable")]
    fold_of_cell[contact_cells] = np.arange(contact_cells.size) % k
    # Free-only cells go to the fold with the fewest free cells so far, so free ground also
    # lies in at least two folds.
    free_count = np.bincount(fold_of_cell[contact_cells[has_free[contact_cells]]], minlength=k)
    for cell in order[has_free[order] & ~has_contact[order]]:
        target = int(np.argmin(free_count))
        fold_of_cell[cell] = target
        free_count[target] += 1
    return fold_of_cell[group]


def calibration_splits(bins: Bins, folds: int, seed: int) -> list[tuple[Bins, Bins]]:
    """``(training, held-out)`` pairs whose held-out decision values Platt's sigmoid is fitted on.

    Each fold's bins are held out, and the training set is the other folds' bins merged per
    (cell, class), when that holds both classes. When the held-out bins of such folds lack
    a class (a handful of contact observations that all hashed to one fold), whole cells
    are held out instead (:func:`cell_folds`) from the bins merged over folds.

    Raises
    ------
    ValueError
        When fewer than two cells hold a bin of either class.
    """
    splits = []
    for fold in np.unique(bins.keys[:, 3]):
        train = merge_folds(bins, exclude=float(fold))
        if np.unique(train.labels).size == 2:
            splits.append((train, bins.select(bins.keys[:, 3] == fold)))
    scored = np.concatenate([held.labels for _, held in splits]) if splits else np.empty(0)
    if np.unique(scored).size == 2:
        return splits
    merged = merge_folds(bins)
    by_cell = cell_folds(merged.keys, folds, seed)
    return [
        (merged.select(by_cell != fold), merged.select(by_cell == fold))
        for fold in np.unique(by_cell)
    ]


def platt_fit(
    decision: FloatArray, labels: NDArray[np.int64], weights: FloatArray
) -> tuple[float, float]:
    """Platt's sigmoid ``P(contact) = sigmoid(slope * f + intercept)`` with ``slope >= 0``.

    Maximum likelihood with Platt's smoothed targets ``(w1 + 1) / (w1 + 2)`` and
    ``1 / (w0 + 2)`` (``w`` the summed weights of a class), as scikit-learn's
    ``_sigmoid_calibration``, whose ``A`` is ``-slope``; but the slope is bounded below by
    zero, so the link is monotone non-decreasing and cannot invert the decision function.

    Parameters
    ----------
    decision : (n,) float64
        Out-of-fold decision values (positive means contact).
    labels : (n,) int
        0 free, 1 contact.
    weights : (n,) float64
        Positive sample weights (a weight ``k`` counts as ``k`` repeated samples).
    """
    from scipy.optimize import minimize
    from scipy.special import expit

    f = np.asarray(decision, dtype=np.float64)
    y = np.asarray(labels) > 0
    w = np.asarray(weights, dtype=np.float64)
    # Large scores (heavily weighted bins) are scaled for the optimiser, as scikit-learn does;
    # the fitted slope is scaled back.
    scale = float(np.max(np.abs(f))) if f.size else 0.0
    scale = scale if scale >= 30.0 else 1.0
    f = f / scale
    w1, w0 = float(w[y].sum()), float(w[~y].sum())
    target = np.where(y, (w1 + 1.0) / (w1 + 2.0), 1.0 / (w0 + 2.0))

    def loss(params: FloatArray) -> tuple[float, FloatArray]:
        z = params[0] * f + params[1]
        residual = w * (expit(z) - target)
        value = float(np.sum(w * (np.logaddexp(0.0, z) - target * z)))
        return value, np.array([float(residual @ f), float(residual.sum())])

    rate = float(np.sum(w * target) / np.sum(w))
    start = np.array([0.0, np.log(rate / (1.0 - rate))])
    result = minimize(
        loss, start, jac=True, method="L-BFGS-B", bounds=[(0.0, None), (None, None)],
        options={"gtol": 1e-6, "ftol": 64 * np.finfo(np.float64).eps},
    )
    slope, intercept = (float(v) for v in result.x)
    return max(slope, 0.0) / scale, intercept
