"""The baseline: rake every coverage line in plain order, alternating direction."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import BuildContext, ExploratoryMovement

from ._base import LinePlanner
from ._config import CoverageConfig
from ._functional import parallel_lines

__all__ = ["BoustrophedonCoverage"]

FloatArray = NDArray[np.float64]


class BoustrophedonCoverage(LinePlanner):
    """Boustrophedon coverage: line 1 forwards, line 2 backwards, ... every line, no early stop.

    Interactions do not change the plan; the metrics count every movement as phase 1
    (``ems_phase2`` is 0), so the baseline compares directly with the two-phase planner.
    """

    config: CoverageConfig

    def __init__(self, config: CoverageConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.reset()

    def reset(self) -> None:
        """Start again from the first line."""
        super().reset()
        starts, ends = parallel_lines(
            self.search_bounds, self.phase1_angle_deg, self.config.line_spacing_m
        )
        self.lines: tuple[FloatArray, FloatArray] = (starts, ends)
        self._next = 0

    @property
    def line_count(self) -> int:
        return len(self.lines[0])

    @property
    def phase(self) -> str:
        """``"coverage"`` while lines remain, then ``"done"``."""
        done = self._next >= min(self.line_count, self.max_movements)
        return "done" if done else "coverage"

    def propose(self) -> ExploratoryMovement | None:
        """The next line, reversed on every other line; None after the last."""
        if self._next >= min(self.line_count, self.max_movements):
            return None
        i = self._next
        self._next += 1
        start, end = self.lines[0][i], self.lines[1][i]
        if i % 2 == 1:
            start, end = end, start
        return self.make_movement(start, end, "coverage", f"line {i + 1}/{self.line_count}")

    def phase_metrics(self) -> dict[str, int]:
        """Every finished movement counts as phase 1."""
        return {"ems_phase1": len(self._finished), "ems_phase2": 0}
