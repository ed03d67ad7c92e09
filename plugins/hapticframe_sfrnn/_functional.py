"""Array functions of the contact-state classifiers (numpy only, testable alone).

- :func:`assemble_inputs` turns a :class:`SampleBatch` into one float64 matrix of the
  configured channels, zero-filling absent, flagged or non-finite parts (Table A.1's
  "tested with fewer modalities") and reporting what it filled.
- :func:`window_starts` and :func:`split_trials` build the thesis's training set:
  sliding 500 ms windows, 10-frame steps over free-movement trials and 5-frame steps over
  trials with contact, with validation held out by whole trials.
- :func:`softmax_rows`, :func:`sigmoid_pair` and :func:`balanced_accuracy` are the
  guarded numerics used on the outputs; :func:`contact_figures` reads a group of scored
  trials the way a teleoperator would (missed contact, false alarms, late onset).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from importlib.metadata import PackageNotFoundError, version

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.kinds import SampleBatch

__all__ = [
    "FillReport",
    "assemble_inputs",
    "balanced_accuracy",
    "check_labels",
    "contact_figures",
    "rms_scale",
    "sigmoid_pair",
    "softmax_rows",
    "split_trials",
    "version_of",
    "window_starts",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

# Inputs beyond this magnitude after scaling carry no more information to a saturating
# network, and clipping keeps float32 matrix products finite (1e30 inputs would overflow).
INPUT_CLIP = 1e6


@dataclass
class FillReport:
    """Frames whose input group was zero-filled, per group, accumulated over calls."""

    absent_frames: dict[str, int] = field(default_factory=dict)
    invalid_frames: dict[str, int] = field(default_factory=dict)

    def add(self, name: str, absent: int, invalid: int) -> None:
        self.absent_frames[name] = self.absent_frames.get(name, 0) + absent
        self.invalid_frames[name] = self.invalid_frames.get(name, 0) + invalid

    def as_dict(self) -> dict[str, dict[str, int]]:
        return {
            "absent_frames": dict(self.absent_frames),
            "invalid_frames": dict(self.invalid_frames),
        }


def assemble_inputs(
    batch: SampleBatch,
    groups: Mapping[str, int],
    report: FillReport | None = None,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """The configured channels side by side, one row per frame.

    Parameters
    ----------
    batch : SampleBatch
    groups : mapping of str to int
        Channel name → flattened size per frame, in column order.
    report : FillReport, optional
        Updated with the frames zero-filled per channel.

    Returns
    -------
    x : (n, sum(sizes)) float64
        Finite values; a channel that is absent, flagged invalid in ``batch.valid`` or holds
        NaN/infinity in a frame is all zeros in that frame.
    present : (n, len(groups)) bool
        Which channel was used as given in each frame.

    Raises
    ------
    ValueError
        When a present channel's per-frame size differs from the configured one.
    """
    n = len(batch)
    width = int(sum(groups.values()))
    x = np.zeros((n, width))
    present = np.zeros((n, len(groups)), dtype=bool)
    col = 0
    for j, (name, size) in enumerate(groups.items()):
        if name not in batch.channels:
            if report is not None:
                report.add(name, n, 0)
            col += size
            continue
        values = np.asarray(batch.channels[name], dtype=np.float64)
        values = values.reshape(n, math.prod(values.shape[1:]))
        if values.shape[1] != size:
            raise ValueError(
                f"channel {name!r} has {values.shape[1]} values per frame, the classifier "
                f"was built for {size}"
            )
        ok = np.isfinite(values).all(axis=1)
        if name in batch.valid:
            ok &= np.asarray(batch.valid[name], dtype=bool)
        bad = n - int(np.count_nonzero(ok))
        # This runs every frame of a stream: the plain copy when all is well (the usual case).
        if bad:
            x[ok, col : col + size] = values[ok]
        else:
            x[:, col : col + size] = values
        present[:, j] = ok
        if report is not None:
            report.add(name, 0, bad)
        col += size
    return x, present


def rms_scale(
    x: FloatArray, group_sizes: Sequence[int] | None = None, floor: float = 1e-12
) -> FloatArray:
    """Root mean square per column group (one value per group, repeated over its columns).

    Scaling by the RMS without centring keeps zero at zero, so a zero-filled modality means
    "no activation" before and after scaling, as the sparse coder's own zero code does. One
    scale per modality (not per column) keeps the relative sizes of a code's atoms: a
    rarely used atom scaled on its own would be blown up to unit RMS and overfitted.
    Groups that are (near) zero get scale 1; ``group_sizes=None`` means one column each.
    """
    x = np.asarray(x, dtype=np.float64)
    if x.ndim != 2:
        raise ValueError(f"expected (n, d), got shape {x.shape}")
    sizes = [1] * x.shape[1] if group_sizes is None else [int(s) for s in group_sizes]
    if sum(sizes) != x.shape[1]:
        raise ValueError(f"group sizes {sizes} do not add up to {x.shape[1]} columns")
    scale = np.ones(x.shape[1])
    if x.shape[0] == 0:
        return scale
    col = 0
    for size in sizes:
        rms = float(np.sqrt(np.mean(np.square(x[:, col : col + size]))))
        scale[col : col + size] = rms if rms > floor else 1.0
        col += size
    return scale


def check_labels(labels: ArrayLike, n: int, n_classes: int) -> IntArray:
    """Integer labels in ``[0, n_classes)``, one per frame, or a clear ValueError."""
    y = np.asarray(labels)
    if y.shape != (n,):
        raise ValueError(f"labels have shape {y.shape}, expected ({n},) (one per frame)")
    if y.size and not np.all(np.isfinite(y.astype(np.float64))):
        raise ValueError("labels contain NaN or infinity")
    yi = y.astype(np.int64)
    if y.size and (not np.array_equal(yi, y) or yi.min() < 0 or yi.max() >= n_classes):
        raise ValueError(f"labels must be integers in [0, {n_classes})")
    return yi


def window_starts(n: int, window: int, stride: int) -> IntArray:
    """Start indices of length-``window`` windows stepped by ``stride`` over ``n`` frames.

    The last window is aligned with the end so the trial's last frames are covered; a trial
    shorter than the window gives one start (0), to be padded by the caller.
    """
    if window < 1 or stride < 1:
        raise ValueError("window and stride must be at least 1")
    if n <= window:
        return np.zeros(1 if n > 0 else 0, dtype=np.int64)
    starts = np.arange(0, n - window + 1, stride, dtype=np.int64)
    if starts[-1] != n - window:
        starts = np.append(starts, n - window)
    return starts


def split_trials(
    has_contact: Sequence[bool], fraction: float, rng: np.random.Generator
) -> tuple[IntArray, IntArray]:
    """Training and validation trial indices, stratified by whether a trial has contact.

    Each stratum gives ``round(fraction * size)`` trials to validation, at least one when
    it has two or more and ``fraction > 0``; with ``fraction == 0`` nothing is held out.
    """
    flags = np.asarray(has_contact, dtype=bool)
    train: list[int] = []
    val: list[int] = []
    for kind in (True, False):
        ids = np.flatnonzero(flags == kind)
        ids = ids[rng.permutation(ids.size)]
        k = round(fraction * ids.size)
        if fraction > 0 and ids.size >= 2:
            k = max(k, 1)
        k = min(k, ids.size - 1) if ids.size else 0
        val += ids[:k].tolist()
        train += ids[k:].tolist()
    return np.sort(np.array(train, dtype=np.int64)), np.sort(np.array(val, dtype=np.int64))


def softmax_rows(logits: ArrayLike) -> FloatArray:
    """Row-wise softmax in float64 with the max subtracted (no overflow, rows sum to 1)."""
    z = np.asarray(logits, dtype=np.float64)
    if z.ndim != 2:
        raise ValueError(f"expected (n, k) logits, got shape {z.shape}")
    z = np.where(np.isfinite(z), z, 0.0)  # a non-finite logit never reaches the output
    z = z - z.max(axis=1, keepdims=True, initial=-np.inf) if z.size else z
    e = np.exp(z)
    return e / e.sum(axis=1, keepdims=True)


def sigmoid_pair(score: ArrayLike) -> FloatArray:
    """``[1 - p, p]`` with ``p = expit(score)``, evaluated without overflow."""
    from scipy.special import expit

    s = np.nan_to_num(np.asarray(score, dtype=np.float64), nan=0.0)
    p = expit(s)
    return np.column_stack([expit(-s), p]) if s.size else np.empty((0, 2))


def balanced_accuracy(y_true: ArrayLike, y_pred: ArrayLike, n_classes: int = 2) -> float:
    """Mean per-class recall over the classes present in ``y_true`` (NaN-free)."""
    t = np.asarray(y_true, dtype=np.int64)
    p = np.asarray(y_pred, dtype=np.int64)
    recalls = [float(np.mean(p[t == c] == c)) for c in range(n_classes) if np.any(t == c)]
    if not recalls:
        raise ValueError("no labelled frames to score")
    return float(np.mean(recalls))


def contact_figures(
    truth: Sequence[ArrayLike], predicted: Sequence[ArrayLike]
) -> dict[str, float | int | None]:
    """Frame and onset figures of a group of scored trials.

    Parameters
    ----------
    truth, predicted : sequence of arrays
        Per trial, the frame labels and the predicted states (0 free, 1 contact).

    Returns
    -------
    dict
        ``balanced_accuracy`` over the pooled frames; ``contact_recall`` (share of contact
        frames read as contact) and ``free_specificity`` (share of free frames read as
        free), None when the group has no frame of that class; ``onset_delay_frames``, the
        median over trials with contact of the frames from the first contact frame to the
        first frame read as contact within the contact (0 when the reading began earlier),
        None when no contact was read; ``missed_contacts``, the trials whose contact was
        never read; ``contact_trials``, ``trials`` and ``frames``.

    Raises
    ------
    ValueError
        For no trials, a trial whose two arrays differ in length, or no frames at all.
    """
    if len(truth) != len(predicted) or not truth:
        raise ValueError(f"need labels and predictions of the same trials, got {len(truth)} "
                         f"and {len(predicted)}")
    ys = [np.asarray(t, dtype=np.int64).ravel() for t in truth]
    ps = [np.asarray(p, dtype=np.int64).ravel() for p in predicted]
    delays, missed, with_contact = [], 0, 0
    for i, (y, p) in enumerate(zip(ys, ps, strict=True)):
        if y.shape != p.shape:
            raise ValueError(f"trial {i}: {y.size} labels but {p.size} predictions")
        contact = np.flatnonzero(y == 1)
        if contact.size == 0:
            continue
        with_contact += 1
        read = np.flatnonzero(p[contact[0]:contact[-1] + 1] == 1)
        if read.size:
            delays.append(int(read[0]))
        else:
            missed += 1
    y, p = np.concatenate(ys), np.concatenate(ps)
    in_contact, free = y == 1, y == 0
    return {
        "balanced_accuracy": balanced_accuracy(y, p),
        "contact_recall": float(np.mean(p[in_contact] == 1)) if in_contact.any() else None,
        "free_specificity": float(np.mean(p[free] == 0)) if free.any() else None,
        "onset_delay_frames": float(np.median(delays)) if delays else None,
        "missed_contacts": missed,
        "contact_trials": with_contact,
        "trials": len(ys),
        "frames": int(y.size),
    }


def version_of(distribution: str) -> str | None:
    """Installed version of a distribution, or None."""
    try:
        return version(distribution)
    except PackageNotFoundError:
        return None
