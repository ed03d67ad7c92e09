"""The ``contact-point`` sensor model: the classifier's contact probability at the fingertip.

The belief map of Jia (2022, §2.5) samples the spatial distribution at the fingertip only:
each SF-RNN step gives one observation at the fingertip's (x, y) with the contact
probability as its target and weight 1. The model also keeps the contact-state timeline
(time, probability, position) and draws it as Fig. 2.5d when the run finishes.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import (
    BuildContext,
    LocatedMeasurement,
    Observations,
    RunOutcome,
    SensorModel,
)

from . import _functional as fn
from ._config import ContactPointConfig

__all__ = ["ContactPoint", "contact_events"]

FloatArray = NDArray[np.float64]


def contact_events(targets: FloatArray) -> tuple[int | None, int | None]:
    """Index of the first and the last sample decided as contact (target > 0.5)."""
    decided = np.flatnonzero(np.asarray(targets) > 0.5)
    if decided.size == 0:
        return None, None
    return int(decided[0]), int(decided[-1])


class ContactPoint(SensorModel):
    """One observation per located sample: target = P(contact), at the fingertip, weight 1."""

    config: ContactPointConfig

    def __init__(self, config: ContactPointConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.reset()

    def reset(self) -> None:
        """Forget the recorded timeline."""
        self._n = 0
        self._timeline = np.empty((256, 4))  # t, target, x, y

    @property
    def timeline(self) -> dict[str, FloatArray]:
        """Copies of the recorded ``timestamps_s``, ``contact_probability`` and ``positions_m``."""
        rows = self._timeline[: self._n]
        return {
            "timestamps_s": rows[:, 0].copy(),
            "contact_probability": rows[:, 1].copy(),
            "positions_m": rows[:, 2:4].copy(),
        }

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        """Observations at the fingertip positions with the contact probability as target."""
        if not isinstance(measurement, LocatedMeasurement):
            raise TypeError(
                f"observe expects a LocatedMeasurement, got {type(measurement).__name__}"
            )
        targets = fn.contact_targets(
            measurement.probabilities, measurement.classes, self.config.contact_class,
            self.config.class_targets,
        )
        n = len(measurement)
        if n == 0:
            return Observations.empty()
        self._record(measurement.timestamps_s, targets, measurement.positions_m)
        return Observations(measurement.positions_m, targets, np.ones(n))

    def _record(self, t: FloatArray, targets: FloatArray, positions: FloatArray) -> None:
        n = len(t)
        needed = self._n + n
        if needed > len(self._timeline):
            grown = np.empty((max(needed, 2 * len(self._timeline)), 4))
            grown[: self._n] = self._timeline[: self._n]
            self._timeline = grown
        self._timeline[self._n:needed] = np.column_stack([t, targets, positions])
        self._n = needed

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write ``timeline.png`` (Fig. 2.5d) and return the contact event times."""
        data = self.timeline
        first, last = contact_events(data["contact_probability"])
        t = data["timestamps_s"]
        if outcome.figures and self._n:
            from ._plots import save_timeline_figure

            save_timeline_figure(
                Path(outcome.out_dir) / "timeline.png", t, data["contact_probability"],
                data["positions_m"], first, last,
            )
        decided = data["contact_probability"] > 0.5
        return {
            "contact_first_s": None if first is None else float(t[first]),
            "contact_last_s": None if last is None else float(t[last]),
            "contact_fraction": float(decided.mean()) if self._n else 0.0,
        }
