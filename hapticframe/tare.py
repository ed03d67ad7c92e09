"""Causal tare: each channel of a recording minus its mean over the recording's first frames.

Sensors that rest at their own levels (a BioTac's electrodes and fluid pressure, a
force-torque sensor's offsets) are zeroed before a trial. Subtracting the mean of the first
``n_frames`` frames removes those per-sensor, per-trial offsets, which a classifier would
otherwise learn instead of the contact.

The tare is causal, so streaming and batch agree: frame ``k < n_frames`` is referred to the
mean of frames ``0..k`` (frame 0 therefore becomes zero), later frames to the mean of the
first ``n_frames``. Invalid or non-finite frames (``valid`` False) are left out of the
mean; until the first valid frame the reference is zero (values pass through unchanged).

The ``biotac`` sensor (``tare_frames``) and the ``recording`` sensor (``tare_frames``) both
use it, so a BioTac recording replayed either way is zeroed identically.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["TareState", "tare_reference"]

FloatArray = NDArray[np.float64]


def tare_reference(
    values: ArrayLike, n_frames: int, valid: ArrayLike | None = None
) -> FloatArray:
    """The causal tare reference of every frame (same shape as ``values``).

    Parameters
    ----------
    values : (n, ...) array
        One row per frame.
    n_frames : int
        Frames averaged into the reference (≥ 1).
    valid : (n,) bool, optional
        Frames that may enter the mean; default all.

    Returns
    -------
    (n, ...) float64
        Row k holds the mean of the valid frames among the first ``min(k + 1, n_frames)``;
        zero while none of them is valid.
    """
    state = TareState(n_frames)
    return state.reference(values, valid)


class TareState:
    """Streaming tare of one recording: feed frames in order, get each frame's reference.

    Parameters
    ----------
    n_frames : int
        Frames averaged into the reference (≥ 1).
    """

    def __init__(self, n_frames: int) -> None:
        if int(n_frames) < 1:
            raise ValueError(f"n_frames must be at least 1, got {n_frames}")
        self.n_frames = int(n_frames)
        self.reset()

    def reset(self) -> None:
        """Start a new recording."""
        self._seen = 0
        self._sum: FloatArray | None = None
        self._count = 0

    def reference(self, values: ArrayLike, valid: ArrayLike | None = None) -> FloatArray:
        """References of the next frames of the recording (and advance the state)."""
        x = np.asarray(values, dtype=np.float64)
        n = x.shape[0]
        ok = np.ones(n, dtype=bool) if valid is None else np.asarray(valid, dtype=bool)
        if ok.shape != (n,):
            raise ValueError(f"valid must have shape ({n},), got {ok.shape}")
        ok = ok & np.isfinite(x.reshape(n, -1)).all(axis=1)
        if self._sum is None:
            self._sum = np.zeros(x.shape[1:])
        # Frames still inside the averaging span: running sums of the valid ones.
        inside = np.clip(self.n_frames - self._seen, 0, n)
        weights = ok[:inside].astype(np.float64)
        increments = np.where(ok[:inside].reshape(-1, *([1] * (x.ndim - 1))), x[:inside], 0.0)
        sums = self._sum + np.cumsum(increments, axis=0) if inside else np.empty((0, *x.shape[1:]))
        counts = self._count + np.cumsum(weights) if inside else np.empty(0)
        if inside:
            self._sum = sums[-1].copy()
            self._count = int(counts[-1])
        self._seen += n
        final = self._sum / self._count if self._count else np.zeros(x.shape[1:])
        out = np.empty_like(x)
        if inside:
            shaped = counts.reshape(-1, *([1] * (x.ndim - 1)))
            out[:inside] = np.where(shaped > 0, sums / np.maximum(shaped, 1.0), 0.0)
        out[inside:] = final
        return out
