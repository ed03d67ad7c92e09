"""Calibration recordings: what a trainable sensor model learns from (issue 32 §2).

A lab buries an object where it knows it and records movements past it. Each recording
gives, per sample, where the plate was (position, heading, depth), which movement the
sample belongs to and what the classifier reported (class probabilities); and, once per
recording, the known objects (their outlines in the map frame, from the scene's shape and
pose). :class:`CalibrationRecording` holds exactly that, validated, in float64.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["CalibrationRecording"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True, init=False)
class CalibrationRecording:
    """One calibration recording: plate poses, classifier outputs and the known objects.

    Parameters
    ----------
    timestamps_s : (n,) array
        Sample times, non-decreasing.
    positions_m : (n, 2) array
        Plate (fingertip) position in the map frame.
    headings_rad : (n,) array
        Direction of motion, counter-clockwise from +x.
    depth_m : (n,) array
        Plate depth below the free surface (NaN where unknown).
    movement_index : (n,) int array
        Which movement each sample belongs to, non-decreasing.
    probabilities : (n, k) array
        The classifier's class probabilities (a one-hot row for a hard label).
    classes : sequence of str
        The ``k`` class names, in column order.
    outlines_m : sequence of (m, 2) arrays
        Each known object's outline in the map frame (its shape placed at its pose).
    source : str, optional
        Where the recording came from, for messages.

    Raises
    ------
    ValueError
        When shapes disagree, values are not finite (depth may be NaN) or the movement
        index decreases; the message names ``source``.
    """

    timestamps_s: FloatArray
    positions_m: FloatArray
    headings_rad: FloatArray
    depth_m: FloatArray
    movement_index: IntArray
    probabilities: FloatArray
    classes: tuple[str, ...]
    outlines_m: tuple[FloatArray, ...]
    source: str

    def __init__(
        self,
        timestamps_s: ArrayLike,
        positions_m: ArrayLike,
        headings_rad: ArrayLike,
        depth_m: ArrayLike,
        movement_index: ArrayLike,
        probabilities: ArrayLike,
        classes: Sequence[str],
        outlines_m: Sequence[ArrayLike],
        source: str = "calibration recording",
    ) -> None:
        where = source
        t = np.asarray(timestamps_s, dtype=np.float64).reshape(-1)
        n = t.size
        p = np.asarray(positions_m, dtype=np.float64)
        h = np.asarray(headings_rad, dtype=np.float64).reshape(-1)
        d = np.asarray(depth_m, dtype=np.float64).reshape(-1)
        m = np.asarray(movement_index)
        q = np.asarray(probabilities, dtype=np.float64)
        names = tuple(str(c) for c in classes)
        if p.shape != (n, 2):
            raise ValueError(f"{where}: positions_m must be ({n}, 2), got {p.shape}")
        for name, arr in (("headings_rad", h), ("depth_m", d), ("movement_index", m)):
            if arr.shape != (n,):
                raise ValueError(f"{where}: {name} must have {n} values, got {arr.shape}")
        if q.shape != (n, len(names)) or not names:
            raise ValueError(f"{where}: probabilities must be ({n}, {len(names)}) for classes "
                             f"{names}, got {q.shape}")
        for name, arr in (("timestamps_s", t), ("positions_m", p), ("headings_rad", h),
                          ("probabilities", q)):
            if not np.all(np.isfinite(arr)):
                raise ValueError(f"{where}: {name} holds NaN or infinity")
        if n and (np.any(np.diff(t) < 0) or np.any(np.diff(m) < 0)):
            raise ValueError(f"{where}: timestamps_s and movement_index must not decrease")
        if not np.all(np.equal(np.mod(m, 1), 0)):
            raise ValueError(f"{where}: movement_index must hold integers")
        outlines = []
        for i, o in enumerate(outlines_m):
            arr = np.asarray(o, dtype=np.float64)
            if arr.ndim != 2 or arr.shape[1] != 2 or len(arr) < 3 or not np.all(np.isfinite(arr)):
                raise ValueError(f"{where}: outline {i} must be a finite (m >= 3, 2) array")
            outlines.append(arr)
        if not outlines:
            raise ValueError(f"{where}: a calibration recording needs its known object(s)")
        for name, value in (("timestamps_s", t), ("positions_m", p), ("headings_rad", h),
                            ("depth_m", d), ("movement_index", m.astype(np.int64)),
                            ("probabilities", q), ("classes", names),
                            ("outlines_m", tuple(outlines)), ("source", source)):
            object.__setattr__(self, name, value)

    def __len__(self) -> int:
        return int(self.timestamps_s.size)

    def labels(self) -> IntArray:
        """The arg-max class index of each sample."""
        labels: IntArray = np.argmax(self.probabilities, axis=1).astype(np.int64)
        return labels
