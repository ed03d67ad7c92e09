"""Pure array functions of the force/force-rate interaction classifier.

The decision rule follows thesis Figure 3.4: a sample sits in a 2-D space of filtered force
``F`` and force rate ``R``; it is "jamming" when both exceed the jamming thresholds and
"contact" when both exceed the contact thresholds. The soft version used for probabilities
keeps exactly that rule as its arg-max.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import softmax

__all__ = [
    "MAX_FORCE_N",
    "Thresholds",
    "and_rule_margin",
    "balanced_accuracy",
    "best_and_thresholds",
    "free_drag_floor",
    "candidate_thresholds",
    "first_flag_indices",
    "force_magnitude",
    "hard_states",
    "plateau_argmax",
    "quadrant_counts",
    "state_probabilities",
]

FloatArray = NDArray[np.float64]

#: Force magnitudes are clipped here so that filter arithmetic can never overflow.
MAX_FORCE_N = 1e12
# Logits beyond this are already 0 or 1 after the softmax; clipping keeps inf out of it.
_MAX_LOGIT = 1e6

Thresholds = tuple[float, float, float, float]
"""(jamming force, jamming rate, contact force, contact rate)."""


def force_magnitude(values: ArrayLike) -> FloatArray:
    """Magnitude per sample: ``|x|`` for scalar channels, the Euclidean norm for vectors.

    Rows are scaled by their largest component before squaring, so huge forces do not
    overflow; non-finite components give NaN for that row; results are clipped at
    :data:`MAX_FORCE_N`.
    """
    x = np.asarray(values, dtype=np.float64)
    if x.ndim == 0:
        raise ValueError("force values need a sample axis")
    x = np.abs(x.reshape(x.shape[0], -1))
    if x.shape[1] == 0:
        raise ValueError("force channel has no components")
    finite = np.all(np.isfinite(x), axis=1)
    safe = np.where(np.isfinite(x), x, 0.0)
    peak = safe.max(axis=1)
    scale = np.where(peak > 0, peak, 1.0)
    out = peak * np.sqrt(np.sum((safe / scale[:, None]) ** 2, axis=1))
    out = np.minimum(out, MAX_FORCE_N)
    return np.where(finite, out, np.nan)


def and_rule_margin(
    force: ArrayLike,
    rate: ArrayLike,
    force_threshold: float,
    rate_threshold: float,
    force_scale: float,
    rate_scale: float,
) -> FloatArray:
    """Signed distance into the quadrant ``F > f, R > r``: the smaller scaled margin."""
    f = np.asarray(force, dtype=np.float64)
    r = np.asarray(rate, dtype=np.float64)
    return np.minimum((f - force_threshold) / force_scale, (r - rate_threshold) / rate_scale)


def state_probabilities(
    force: ArrayLike, rate: ArrayLike, thresholds: Thresholds, force_scale: float, rate_scale: float
) -> FloatArray:
    """``(n, 3)`` probabilities of free, jamming and contact.

    Logits are ``(0, m_j, m_c + max(m_j, 0))`` for the jamming and contact margins ``m_j``
    and ``m_c``; their arg-max is exactly :func:`hard_states`: contact when ``m_c > 0``,
    otherwise jamming when ``m_j > 0``, otherwise free.
    """
    fj, rj, fc, rc = thresholds
    m_j = and_rule_margin(force, rate, fj, rj, force_scale, rate_scale)
    m_c = and_rule_margin(force, rate, fc, rc, force_scale, rate_scale)
    logits = np.stack([np.zeros_like(m_j), m_j, m_c + np.maximum(m_j, 0.0)], axis=-1)
    logits = np.clip(np.nan_to_num(logits, nan=0.0), -_MAX_LOGIT, _MAX_LOGIT)
    return softmax(logits, axis=-1)


def hard_states(force: ArrayLike, rate: ArrayLike, thresholds: Thresholds) -> NDArray[np.int64]:
    """0 free, 1 jamming, 2 contact by the thresholds alone (the arg-max of the probabilities)."""
    fj, rj, fc, rc = thresholds
    f = np.asarray(force, dtype=np.float64)
    r = np.asarray(rate, dtype=np.float64)
    jam = (f > fj) & (r > rj)
    contact = (f > fc) & (r > rc)
    return np.where(contact, 2, np.where(jam, 1, 0)).astype(np.int64)


def balanced_accuracy(truth: ArrayLike, predicted: ArrayLike) -> float:
    """Mean recall over the classes present in ``truth``."""
    t = np.asarray(truth)
    p = np.asarray(predicted)
    classes = np.unique(t)
    if classes.size == 0:
        raise ValueError("balanced accuracy of an empty set is undefined")
    return float(np.mean([np.mean(p[t == c] == c) for c in classes]))


def candidate_thresholds(values: ArrayLike, labels: ArrayLike, n: int) -> FloatArray:
    """Distinct candidate thresholds: ``n`` quantiles of ``values`` within each class, plus
    one value below all (which lets a rule ignore that axis).

    Per-class quantiles keep the grid fine where the rare interaction samples lie, which
    pooled quantiles (dominated by free movement) would not.
    """
    v = np.asarray(values, dtype=np.float64)
    y = np.asarray(labels)
    keep = np.isfinite(v)
    v, y = v[keep], y[keep]
    if v.size == 0:
        raise ValueError("no finite values to place thresholds between")
    levels = np.linspace(0.0, 1.0, n)
    parts = [np.quantile(v[y == c], levels) for c in np.unique(y)]
    return np.unique(np.concatenate([[v.min() - 1.0], *parts]))


def _count_above(sorted_values: FloatArray, thresholds: FloatArray) -> NDArray[np.int64]:
    """How many of ``sorted_values`` lie strictly above each threshold."""
    return sorted_values.size - np.searchsorted(sorted_values, thresholds, side="right")


def quadrant_counts(
    force: FloatArray,
    rate: FloatArray,
    groups: list[NDArray[np.bool_]],
    force_candidates: FloatArray,
    rate_candidates: FloatArray,
) -> list[NDArray[np.int64]]:
    """For each group mask, ``(n_force, n_rate)`` counts of members with ``F > f`` and ``R > r``."""
    out = []
    for members in groups:
        f = force[members]
        r = rate[members]
        counts = np.zeros((force_candidates.size, rate_candidates.size), dtype=np.int64)
        order = np.argsort(f, kind="stable")
        f_sorted, r_by_f = f[order], r[order]
        for i, threshold in enumerate(force_candidates):
            start = np.searchsorted(f_sorted, threshold, side="right")
            counts[i] = _count_above(np.sort(r_by_f[start:]), rate_candidates)
        out.append(counts)
    return out


def first_flag_indices(
    force: FloatArray, rate: FloatArray, force_candidates: FloatArray, rate_candidates: FloatArray
) -> NDArray[np.int64]:
    """``(n_force, n_rate)`` index of the first sample with ``F > f`` and ``R > r``.

    ``n`` (the number of samples) where no sample qualifies.
    """
    n = force.size
    out = np.full((force_candidates.size, rate_candidates.size), n, dtype=np.int64)
    index = np.arange(n)
    for i, threshold in enumerate(force_candidates):
        above = force > threshold
        if not above.any():
            continue
        order = np.argsort(-rate[above], kind="stable")
        descending = rate[above][order]
        earliest = np.minimum.accumulate(index[above][order])
        # Number of selected samples with rate strictly above each rate threshold.
        count = np.searchsorted(-descending, -rate_candidates, side="left")
        out[i] = np.where(count > 0, earliest[np.maximum(count - 1, 0)], n)
    return out


def plateau_argmax(score: FloatArray) -> tuple[int, int]:
    """Grid cell of maximal score that lies deepest inside the maximal plateau.

    Several threshold pairs often score equally (all events right); the one farthest (in grid
    steps) from any worse pair is the most robust. Remaining ties go to the first cell in
    row-major order, so the choice is deterministic.
    """
    from scipy.ndimage import distance_transform_cdt

    best = score >= np.max(score)
    padded = np.pad(best, 1, constant_values=False)
    depth = distance_transform_cdt(padded, metric="chessboard")[1:-1, 1:-1]
    i, j = np.unravel_index(int(np.argmax(np.where(best, depth, -1))), score.shape)
    return int(i), int(j)


Recording = tuple[ArrayLike, ArrayLike, ArrayLike]
"""(filtered force, force rate, labels) of one movement."""


def _event_scores(
    recordings: list[tuple[FloatArray, FloatArray, NDArray[np.int64]]],
    force_candidates: FloatArray,
    rate_candidates: FloatArray,
) -> FloatArray:
    """Balanced accuracy of first decisions: quiet free stretches vs approaches caught jamming."""
    shape = (force_candidates.size, rate_candidates.size)
    quiet, caught = np.zeros(shape), np.zeros(shape)
    n_free = n_approach = 0
    for f, r, y in recordings:
        first = first_flag_indices(f, r, force_candidates, rate_candidates)
        engaged = np.flatnonzero(y >= 1)
        onset = int(engaged[0]) if engaged.size else y.size
        if onset > 0:  # a free stretch before any interaction
            n_free += 1
            quiet += first >= onset
        if engaged.size:
            n_approach += 1
            truth_at_first = np.append(y, -1)[first]
            caught += truth_at_first == 1
    if n_free == 0 or n_approach == 0:
        raise ValueError("event calibration needs free stretches and approaches that reach jamming")
    return 0.5 * quiet / n_free + 0.5 * caught / n_approach


def best_and_thresholds(
    recordings: list[Recording],
    n_candidates: int = 96,
    base: Thresholds | None = None,
    objective: str = "events",
    force_floor: float | None = None,
) -> tuple[Thresholds, float]:
    """Thresholds of the two AND rules that maximise balanced accuracy on labelled movements.

    The jamming quadrant is chosen first, by one of two objectives:

    ``"events"``
        Balanced accuracy of each movement's *first* non-free decision (what halts a run):
        recall of free stretches that raise no alarm, and recall of approaches whose first
        alarm falls in jamming (before contact).
    ``"samples"``
        Per-sample balanced accuracy of free vs interaction (1 or 2). Labels begin at the
        geometric onset, before the force shows anything, so this favours hair-trigger
        thresholds.

    Then, when contact samples exist, the contact quadrant (at or above the jamming
    thresholds) maximises per-sample three-class balanced accuracy. Ties resolve with
    :func:`plateau_argmax`, so the result is deterministic.

    Parameters
    ----------
    recordings : list of (force, rate, labels)
        One triple of ``(n_i,)`` arrays per movement; non-finite samples are ignored.
        Labels: 0 free, 1 jamming, 2 contact.
    n_candidates : int
        Quantiles per class and axis that serve as candidate thresholds.
    base : Thresholds or None
        Contact thresholds to keep (raised to at least the jamming ones) when no contact
        samples are given; None makes them infinite (contact is never predicted).
    objective : {"events", "samples"}
    force_floor : float or None
        The jamming force threshold is chosen among candidates at or above this force (the
        floor itself is one); None places no floor. See :func:`free_drag_floor`.

    Returns
    -------
    thresholds : Thresholds
    score : float
        The maximised stage-1 score.
    """
    if objective not in ("events", "samples"):
        raise ValueError(f"objective must be 'events' or 'samples', got {objective!r}")
    clean = []
    for k, (force, rate, labels) in enumerate(recordings):
        f = np.asarray(force, dtype=np.float64)
        r = np.asarray(rate, dtype=np.float64)
        y = np.asarray(labels).astype(np.int64)
        if not (f.shape == r.shape == y.shape and f.ndim == 1):
            raise ValueError(f"recording {k}: force, rate and labels must be 1-D of equal length")
        if np.any((y < 0) | (y > 2)):
            raise ValueError(f"recording {k}: labels must be 0 (free), 1 (jamming) or 2 (contact)")
        keep = np.isfinite(f) & np.isfinite(r)
        clean.append((f[keep], r[keep], y[keep]))
    if not clean:
        raise ValueError("calibration needs at least one recording")
    f, r, y = (np.concatenate(parts) for parts in zip(*clean, strict=True))
    free, engaged, contact = y == 0, y >= 1, y == 2
    if not free.any() or not engaged.any():
        raise ValueError("calibration needs both free (0) and interaction (1 or 2) samples")
    f_cand = candidate_thresholds(f, y, n_candidates)
    r_cand = candidate_thresholds(r, y, n_candidates)
    if force_floor is not None:
        if not np.isfinite(force_floor):
            raise ValueError(f"force_floor must be finite, got {force_floor!r}")
        f_cand = np.unique(np.append(f_cand[f_cand > force_floor], force_floor))
    # Stage 1: the jamming quadrant.
    if objective == "events":
        score = _event_scores(clean, f_cand, r_cand)
    else:
        above_free, above_engaged = quadrant_counts(f, r, [free, engaged], f_cand, r_cand)
        score = 0.5 * (1.0 - above_free / free.sum()) + 0.5 * above_engaged / engaged.sum()
    i, j = plateau_argmax(score)
    best = float(score[i, j])
    fj, rj = float(f_cand[i]), float(r_cand[j])
    if not contact.any():
        fc, rc = (np.inf, np.inf) if base is None else (max(base[2], fj), max(base[3], rj))
        return (fj, rj, fc, rc), best
    # Stage 2: a contact quadrant inside the jamming one; free recall does not change.
    jam = (f > fj) & (r > rj)
    fc_cand = f_cand[f_cand >= fj]
    rc_cand = r_cand[r_cand >= rj]
    jamming = y == 1
    moved_jamming, caught_contact = quadrant_counts(
        f, r, [jamming & jam, contact & jam], fc_cand, rc_cand
    )
    recalls = [np.full(moved_jamming.shape, np.mean(~jam[free])), caught_contact / contact.sum()]
    if jamming.any():
        recalls.append((np.sum(jamming & jam) - moved_jamming) / jamming.sum())
    k, m = plateau_argmax(sum(recalls) / len(recalls))
    return (fj, rj, float(fc_cand[k]), float(rc_cand[m])), best


def free_drag_floor(recordings: list[Recording]) -> float:
    """The largest steady free-sand drag among labelled movements.

    Per movement, the median filtered force over its free-labelled (0) samples (the median
    ignores the start-up ramp and the sensor's fluctuation); the largest over movements, so
    that a threshold at or above it never alarms in the free sand of the deepest movement.

    Raises
    ------
    ValueError
        When no movement has a finite free-labelled sample.
    """
    medians = []
    for force, _rate, labels in recordings:
        f = np.asarray(force, dtype=np.float64)
        y = np.asarray(labels)
        free = f[(y == 0) & np.isfinite(f)]
        if free.size:
            medians.append(float(np.median(free)))
    if not medians:
        raise ValueError("the free-drag floor needs free-labelled (0) samples")
    return max(medians)
