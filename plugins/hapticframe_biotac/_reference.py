"""A contact reference "derived from pdc", for real recordings that carry no contact labels.

Rule (documented in docs/real-biotac.md): the resting level is the mean of the raw pdc over
the recording's first ``rest_frames`` frames (the fingertip at rest in open air); a frame
is contact once pdc has risen more than ``on_counts`` above that level, and stays contact
until pdc falls below ``off_counts`` above it (hysteresis, so noise at the threshold does
not chatter). Because the reference is read off pdc, any model scored against it should
also be scored without pdc (``hapticframe bench perception-real`` does).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["DERIVED_FROM_PDC", "PdcReference", "derived_from_pdc"]

#: The name the reference goes by everywhere (reports, metadata, docs).
DERIVED_FROM_PDC = "derived from pdc"


class PdcReference:
    """The rule's settings: resting frames and the rise (counts) that starts and ends contact.

    Defaults: 100 frames (1 s at 100 Hz), on at 20 counts, off below 10.
    """

    def __init__(self, rest_frames: int = 100, on_counts: float = 20.0,
                 off_counts: float = 10.0) -> None:
        if int(rest_frames) < 1:
            raise ValueError(f"rest_frames must be at least 1, got {rest_frames}")
        if not (np.isfinite(on_counts) and np.isfinite(off_counts)):
            raise ValueError("on_counts and off_counts must be finite")
        if not 0 <= off_counts <= on_counts:
            raise ValueError(f"need 0 <= off_counts <= on_counts, got off {off_counts}, "
                             f"on {on_counts}")
        self.rest_frames = int(rest_frames)
        self.on_counts = float(on_counts)
        self.off_counts = float(off_counts)

    def as_dict(self) -> dict[str, float | int | str]:
        return {"name": DERIVED_FROM_PDC, "rest_frames": self.rest_frames,
                "on_counts": self.on_counts, "off_counts": self.off_counts}

    def __call__(self, pdc: ArrayLike) -> NDArray[np.int8]:
        return derived_from_pdc(pdc, self.rest_frames, self.on_counts, self.off_counts)


def derived_from_pdc(pdc: ArrayLike, rest_frames: int = 100, on_counts: float = 20.0,
                     off_counts: float = 10.0) -> NDArray[np.int8]:
    """Contact (1) or free (0) per frame from raw pdc counts by the rule above.

    Raises
    ------
    ValueError
        ``pdc`` is not one-dimensional, holds a value that is not finite, or has fewer
        frames than ``rest_frames``; or the thresholds are out of order.
    """
    values = np.asarray(pdc, dtype=np.float64)
    if values.ndim != 1:
        raise ValueError(f"pdc must be one-dimensional, got shape {values.shape}")
    if not np.all(np.isfinite(values)):
        raise ValueError(f"pdc frame {int(np.flatnonzero(~np.isfinite(values))[0])} is not "
                         "finite")
    PdcReference(rest_frames, on_counts, off_counts)  # checks the settings
    if values.size < rest_frames:
        raise ValueError(f"{values.size} frames cannot give {rest_frames} resting frames")
    rise = values - values[:rest_frames].mean()
    out = np.zeros(values.size, dtype=np.int8)
    on = False
    # A two-state machine; a Python loop over ~5,000 frames takes about a millisecond.
    for k, r in enumerate(rise):
        if on and r < off_counts:
            on = False
        elif not on and r > on_counts:
            on = True
        out[k] = on
    return out
