"""Fitting the failure-zone kernel's parameters from recorded movements (issue 29 §2).

A lab that buried an object where it knows it, and raked towards and past it, can read the
kernel's three parameter groups off its recordings:

- *Rupture distance.* Along each movement that becomes jammed, the first jamming sample
  lies where the failure zone ahead of the plate first reaches the object: its distance to
  the object's outline is the rupture distance at that movement's depth. The hybrid and
  analytic schedules take ``r = d (cot α + cot β)``, so a least-squares line through the
  origin, ``r = k d``, gives the shear-band angle ``β = acot(k - cot α)``.
- *Sector angle.* The bearing of the nearest outline point from the plate at those first
  jamming samples, measured from the direction of motion, says how far to the side the zone
  reaches; the half-angle ``η`` is the largest such bearing (Table 3.1's line then starts
  there and does not grow: ``step`` 0, as one recording shows no trend with n).
- *Depth schedule.* The depth of each movement, and whether it interacted (any jamming or
  contact), give the initial depth, the first decrement after an interaction and the ratio
  of later decrements.

All of it is plain numpy on arrays a run records (``trace.npz``'s robot channels and the
world's ``ground_truth.npz`` states); :func:`fit_failure_zone` returns the fitted values and
the :class:`~hapticframe_failure_zone.FailureZoneConfig` fields they set.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["FailureZoneFit", "fit_failure_zone"]

FloatArray = NDArray[np.float64]

#: Labels of the recorded states (a world's ground truth or a classifier's arg-max).
FREE, JAMMING, CONTACT = 0, 1, 2


@dataclass(frozen=True)
class FailureZoneFit:
    """What :func:`fit_failure_zone` measured and fitted (SI units; angles in degrees).

    Attributes
    ----------
    onset_depth_m, onset_distance_m, onset_bearing_deg : tuple of float
        Per movement that became jammed: its depth, the distance from the plate to the
        object's outline at the first jamming sample, and that point's bearing from the
        direction of motion.
    rupture_ratio : float
        ``k`` of the fitted ``r = k d``.
    shear_band_angle_deg : float
        ``β`` from ``k`` at the rake angle used.
    sector_half_angle_deg : float
        ``η``: the largest onset bearing, capped at 90°.
    initial_depth_m, depth_decrement_m, depth_decrement_ratio : float
        The depth schedule.
    """

    onset_depth_m: tuple[float, ...]
    onset_distance_m: tuple[float, ...]
    onset_bearing_deg: tuple[float, ...]
    rupture_ratio: float
    shear_band_angle_deg: float
    sector_half_angle_deg: float
    initial_depth_m: float
    depth_decrement_m: float
    depth_decrement_ratio: float
    rake_angle_deg: float = 90.0
    notes: tuple[str, ...] = field(default_factory=tuple)

    def rupture_distance_m(self, depth_m: float) -> float:
        """The fitted rupture distance at ``depth_m``."""
        return self.rupture_ratio * depth_m

    def config_overrides(self) -> dict[str, Any]:
        """The :class:`~hapticframe_failure_zone.FailureZoneConfig` fields this fit sets."""
        return {
            "shear_band_angle_deg": self.shear_band_angle_deg,
            "rake_angle_deg": self.rake_angle_deg,
            "empirical_eta_base_deg": self.sector_half_angle_deg,
            "empirical_eta_step_deg": 0.0,
            "initial_depth_m": self.initial_depth_m,
            "depth_decrement_m": self.depth_decrement_m,
            "depth_decrement_ratio": self.depth_decrement_ratio,
        }

    def as_dict(self) -> dict[str, Any]:
        """Plain JSON data."""
        return {
            "onset_depth_m": list(self.onset_depth_m),
            "onset_distance_m": list(self.onset_distance_m),
            "onset_bearing_deg": list(self.onset_bearing_deg),
            "rupture_ratio": self.rupture_ratio,
            "shear_band_angle_deg": self.shear_band_angle_deg,
            "sector_half_angle_deg": self.sector_half_angle_deg,
            "initial_depth_m": self.initial_depth_m,
            "depth_decrement_m": self.depth_decrement_m,
            "depth_decrement_ratio": self.depth_decrement_ratio,
            "rake_angle_deg": self.rake_angle_deg,
            "notes": list(self.notes),
            "config": self.config_overrides(),
        }


def _nearest_outline_point(point: FloatArray, outlines: Sequence[FloatArray]) -> FloatArray:
    best, best_d = outlines[0][0], math.inf
    for outline in outlines:
        d = np.hypot(*(outline - point).T)
        k = int(np.argmin(d))
        if d[k] < best_d:
            best, best_d = outline[k], float(d[k])
    return np.asarray(best, dtype=np.float64)


def _depth_schedule(
    depth_m: FloatArray, movement: NDArray[np.int64], state: NDArray[np.int64]
) -> tuple[float, float, float, list[str]]:
    notes: list[str] = []
    movements = np.unique(movement)
    depths = np.array([np.median(depth_m[movement == m]) for m in movements])
    interacted = np.array([bool(np.any(state[movement == m] >= JAMMING)) for m in movements])
    initial = float(depths[0])
    # Depth after each interacting movement, as the schedule applies it.
    after = [float(depths[i + 1]) for i in range(len(movements) - 1) if interacted[i]]
    levels = [initial, *after]
    steps = [a - b for a, b in itertools.pairwise(levels) if a - b > 1e-9]
    if not steps:
        notes.append("no depth change after an interaction: decrement 0, ratio 1")
        return initial, 0.0, 1.0, notes
    ratios = [b / a for a, b in itertools.pairwise(steps)]
    if not ratios:
        notes.append("one depth change only: ratio kept at 1")
    ratio = float(np.clip(np.median(ratios), 0.0, 1.0)) if ratios else 1.0
    return initial, float(steps[0]), ratio, notes


def fit_failure_zone(
    position_m: ArrayLike,
    heading_rad: ArrayLike,
    depth_m: ArrayLike,
    movement_index: ArrayLike,
    state: ArrayLike,
    outlines_m: Sequence[ArrayLike],
    rake_angle_deg: float = 90.0,
) -> FailureZoneFit:
    """Fit the rupture distance, sector half-angle and depth schedule from recordings.

    Parameters
    ----------
    position_m : (n, 2) array
        Plate (fingertip) positions, one per sample.
    heading_rad : (n,) array
        Direction of motion.
    depth_m : (n,) array
        Raking depth below the surface.
    movement_index : (n,) int array
        Which movement each sample belongs to (non-decreasing).
    state : (n,) int array
        0 free, 1 jamming, 2 contact per sample (the world's truth or a classifier's).
    outlines_m : sequence of (m, 2) arrays
        Each buried object's outline, as the lab placed it.
    rake_angle_deg : float
        The plate's angle to the surface, α (90: vertical).

    Raises
    ------
    ValueError
        On mismatched or non-finite input, no outline, or no movement that became jammed
        ahead of the object (nothing to read a rupture distance from).
    """
    p = np.asarray(position_m, dtype=np.float64)
    n = p.shape[0] if p.ndim == 2 else -1
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"position_m must be (n, 2), got shape {p.shape}")
    heading = np.asarray(heading_rad, dtype=np.float64).reshape(-1)
    depth = np.asarray(depth_m, dtype=np.float64).reshape(-1)
    movement = np.asarray(movement_index).astype(np.int64).reshape(-1)
    labels = np.asarray(state).astype(np.int64).reshape(-1)
    for name, arr in (("heading_rad", heading), ("depth_m", depth),
                      ("movement_index", movement), ("state", labels)):
        if arr.shape != (n,):
            raise ValueError(f"{name} must have {n} samples, got {arr.shape[0]}")
    if n == 0:
        raise ValueError("no samples to fit the failure zone on")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(heading)) and np.all(np.isfinite(depth))):
        raise ValueError("positions, headings and depths must be finite")
    if np.any((labels < FREE) | (labels > CONTACT)):
        raise ValueError("state must be 0 (free), 1 (jamming) or 2 (contact)")
    if not 0.0 < rake_angle_deg < 180.0:
        raise ValueError(f"rake_angle_deg must lie in (0, 180), got {rake_angle_deg}")
    outlines = [np.asarray(o, dtype=np.float64).reshape(-1, 2) for o in outlines_m]
    if not outlines or any(len(o) == 0 for o in outlines):
        raise ValueError("at least one non-empty object outline is needed")
    onset_d, onset_r, onset_b = [], [], []
    for m in np.unique(movement):
        rows = np.flatnonzero(movement == m)
        engaged = rows[labels[rows] >= JAMMING]
        # Read only movements whose first interaction is jamming, after some free sand:
        # one that starts jammed or touches first shows no onset distance.
        if engaged.size == 0 or engaged[0] == rows[0] or labels[engaged[0]] != JAMMING:
            continue
        k = int(engaged[0])
        target = _nearest_outline_point(p[k], outlines)
        offset = target - p[k]
        distance = float(np.hypot(*offset))
        if distance <= 0.0 or depth[k] <= 0.0:
            continue
        bearing = math.atan2(offset[1], offset[0]) - heading[k]
        bearing = abs(math.atan2(math.sin(bearing), math.cos(bearing)))
        onset_d.append(float(depth[k]))
        onset_r.append(distance)
        onset_b.append(math.degrees(bearing))
    if not onset_r:
        raise ValueError("no movement became jammed before contact: record approaches that "
                         "reach the object (run.halt_on_interaction: false)")
    d, r = np.asarray(onset_d), np.asarray(onset_r)
    ratio = float(np.dot(r, d) / np.dot(d, d))
    cot_alpha = 1.0 / math.tan(math.radians(rake_angle_deg))
    notes = []
    cot_beta = ratio - cot_alpha
    if cot_beta <= 1.0 / math.tan(math.radians(89.0)):
        notes.append("fitted ratio at or below cot(alpha): shear-band angle capped at 89 deg")
        cot_beta = 1.0 / math.tan(math.radians(89.0))
    beta = math.degrees(math.atan2(1.0, cot_beta))
    beta = min(max(beta, 1.0), 89.0)
    eta = min(max(onset_b), 90.0)
    initial, decrement, dec_ratio, depth_notes = _depth_schedule(depth, movement, labels)
    return FailureZoneFit(
        onset_depth_m=tuple(onset_d),
        onset_distance_m=tuple(onset_r),
        onset_bearing_deg=tuple(onset_b),
        rupture_ratio=ratio,
        shear_band_angle_deg=beta,
        sector_half_angle_deg=eta,
        initial_depth_m=initial,
        depth_decrement_m=decrement,
        depth_decrement_ratio=dec_ratio,
        rake_angle_deg=rake_angle_deg,
        notes=tuple(notes + depth_notes),
    )
