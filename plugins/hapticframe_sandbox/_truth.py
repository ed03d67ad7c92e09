"""The sandbox's ground truth: the state of each step and the truth of each movement."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["CONTACT", "FREE", "JAMMING", "STATE_NAMES", "GroundTruthLog", "MovementTruth",
           "joined"]

FREE, JAMMING, CONTACT = 0, 1, 2
#: Names of the ground-truth states, indexed by state number.
STATE_NAMES = ("free", "jamming", "contact")


@dataclass(frozen=True)
class GroundTruthLog:
    """The simulator's per-step truth, one row per robot step (all movements, in order).

    Attributes
    ----------
    timestamps_s : (n,) float64
    positions_m : (n, 2) float64
    states : (n,) int64
        0 free movement, 1 granular jamming, 2 direct contact.
    forces_n : (n, 2) float64
        True interaction force on the fingertip.
    movement_index : (n,) int64
        0-based exploratory movement each step belongs to.
    depth_m : (n,) float64
        Raking depth of the step's movement.
    """

    timestamps_s: NDArray[np.float64]
    positions_m: NDArray[np.float64]
    states: NDArray[np.int64]
    forces_n: NDArray[np.float64]
    movement_index: NDArray[np.int64]
    depth_m: NDArray[np.float64]

    @property
    def force_magnitude_n(self) -> NDArray[np.float64]:
        return np.hypot(self.forces_n[:, 0], self.forces_n[:, 1])

    def __len__(self) -> int:
        return int(self.timestamps_s.size)


@dataclass(frozen=True)
class MovementTruth:
    """What really happened during one exploratory movement."""

    index: int
    depth_m: float
    rupture_distance_m: float
    side_crescent_angle_deg: float
    start_time_s: float
    end_time_s: float
    jamming_onset_s: float
    contact_onset_s: float
    max_state: int
    max_force_n: float
    halt_reason: str

    @property
    def interacted(self) -> bool:
        """True when the failure zone or the plate reached an object."""
        return self.max_state >= JAMMING


def joined(parts: list[MovementTruth]) -> MovementTruth:
    """One movement's truth from its parts, in time order."""
    if len(parts) == 1:
        return parts[0]
    first, last = parts[0], parts[-1]

    def earliest(values: list[float]) -> float:
        finite = [v for v in values if not math.isnan(v)]
        return min(finite) if finite else math.nan

    return MovementTruth(
        index=first.index,
        depth_m=first.depth_m,
        rupture_distance_m=first.rupture_distance_m,
        side_crescent_angle_deg=first.side_crescent_angle_deg,
        start_time_s=first.start_time_s,
        end_time_s=last.end_time_s,
        jamming_onset_s=earliest([p.jamming_onset_s for p in parts]),
        contact_onset_s=earliest([p.contact_onset_s for p in parts]),
        max_state=max(p.max_state for p in parts),
        max_force_n=max(p.max_force_n for p in parts),
        halt_reason=last.halt_reason,
    )
