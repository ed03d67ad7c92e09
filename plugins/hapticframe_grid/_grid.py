"""The ``occupancy-grid`` map: an OctoMap-style log-odds grid, the thesis's baseline map.

The thesis shows log-odds maps at the end of each planner phase (Fig. 3.5 a, b, f, g); the
grid therefore keeps a copy of its log odds whenever the planner phase changes and draws
one figure per phase when the run finishes.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import logit

from hapticframe.kinds import (
    BuildContext,
    Map,
    MapEstimate,
    MovementResult,
    Observations,
    Region,
    RunOutcome,
)

from . import _functional as fn
from ._config import OccupancyGridConfig

__all__ = ["OccupancyGrid"]

FloatArray = NDArray[np.float64]




def _file_stem(phase: str) -> str:
    """``logodds_<phase>`` with characters unsafe in file names replaced by ``-``."""
    if not phase:
        return "logodds"
    return "logodds_" + re.sub(r"[^A-Za-z0-9_.-]+", "-", phase)


class OccupancyGrid(Map):
    """Log-odds occupancy grid with clamping (hit 0.7, miss 0.4, clamps 0.1192 / 0.971).

    Cells are squares of ``cell_size_m`` starting at the region's lower-left corner; the
    last row and column may extend past the region when its size is not a multiple of the
    cell size. Observations outside the region are ignored; queries outside it return the
    unknown state (mean 0.5, std 0.5).
    """

    config: OccupancyGridConfig

    def __init__(self, config: OccupancyGridConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self._region = context.map_region(config.region)
        width, height = self._region.size_m
        self._shape = fn.grid_shape(width, height, config.cell_size_m)
        if self._shape[0] * self._shape[1] > 50_000_000:
            raise ValueError(f"{self._shape} cells are too many; increase cell_size_m")
        self._log_hit = float(logit(config.probability_hit))
        self._log_miss = float(logit(config.probability_miss))
        self._log_low = float(logit(config.clamping_min))
        self._log_high = float(logit(config.clamping_max))
        self.reset()

    def reset(self) -> None:
        """Forget all observations and phase snapshots."""
        self._log_odds = np.zeros(self._shape[0] * self._shape[1])
        self._snapshots: dict[str, FloatArray] = {}
        self._phase: str | None = None
        self._at_last_movement: FloatArray | None = None

    @property
    def region(self) -> Region:
        return self._region

    @property
    def shape(self) -> tuple[int, int]:
        """Cells along x and y."""
        return self._shape

    @property
    def log_odds(self) -> FloatArray:
        """A copy of the cell log odds, shape ``(nx, ny)`` (x-major)."""
        return self._log_odds.reshape(self._shape).copy()

    @property
    def cell_centers(self) -> tuple[FloatArray, FloatArray]:
        """Cell-centre coordinates ``(xs, ys)``."""
        size = self.config.cell_size_m
        xs = self._region.x_min_m + (np.arange(self._shape[0], dtype=np.float64) + 0.5) * size
        ys = self._region.y_min_m + (np.arange(self._shape[1], dtype=np.float64) + 0.5) * size
        return xs, ys

    @property
    def phase_snapshots(self) -> dict[str, FloatArray]:
        """Log odds ``(nx, ny)`` at the end of each finished planner phase."""
        return {k: v.reshape(self._shape).copy() for k, v in self._snapshots.items()}

    def _cells(self, points_m: ArrayLike) -> tuple[NDArray[np.intp], NDArray[np.bool_]]:
        r = self._region
        return fn.cell_indices(
            points_m, (r.x_min_m, r.y_min_m), r.size_m, self.config.cell_size_m, self._shape
        )

    def update(self, observations: Observations) -> None:
        """Fuse observations one at a time in order (add log odds, then clamp)."""
        if not isinstance(observations, Observations):
            raise TypeError(f"update expects Observations, got {type(observations).__name__}")
        if len(observations) == 0:
            return
        cells, inside = self._cells(observations.points_m)
        increments = fn.observation_increments(
            observations.targets, observations.weights, self._log_hit, self._log_miss
        )
        fn.fuse_clamped(
            self._log_odds, cells[inside], increments[inside], self._log_low, self._log_high
        )

    def _query(self, points_m: NDArray[np.float64]) -> MapEstimate:
        """Probability of the nearest cell (0.5 outside the region) and ``sqrt(p (1 - p))``."""
        cells, inside = self._cells(points_m)
        log_odds = np.where(inside, self._log_odds[cells], 0.0)
        mean = fn.occupancy_probability(log_odds)
        return MapEstimate(mean, fn.occupancy_std(mean))

    def on_movement_end(self, result: MovementResult) -> None:
        """Snapshot the log odds when the planner phase changes.

        The copy kept for a finished phase is the one taken at the end of its last
        movement, i.e. before the first movement of the new phase.
        """
        phase = result.movement.phase
        if self._phase is not None and phase != self._phase and self._at_last_movement is not None:
            self._snapshots[self._phase] = self._at_last_movement
        self._phase = phase
        self._at_last_movement = self._log_odds.copy()

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        """Write ``logodds_<phase>.png`` per phase seen, or ``logodds.png`` without movements."""
        if not outcome.figures:
            return {}
        maps = dict(self._snapshots)
        if self._phase is not None:
            # The last phase ends with the run: show the final map.
            maps[self._phase] = self._log_odds.copy()
        if not maps:
            maps[""] = self._log_odds.copy()
        from ._plots import save_log_odds_figure

        out_dir = Path(outcome.out_dir)
        outlines = [] if outcome.scene is None else [o.outline() for o in outcome.scene.objects]
        movements = list(outcome.movements)
        for phase, values in maps.items():
            # A finished phase's map is the one after its last movement: draw the path so far.
            ends = [i for i, r in enumerate(movements) if r.movement.phase == phase]
            shown = movements if phase == self._phase or not ends else movements[: ends[-1] + 1]
            save_log_odds_figure(
                out_dir / f"{_file_stem(phase)}.png",
                self._region,
                self.config.cell_size_m,
                values.reshape(self._shape),
                (self._log_low, self._log_high),
                title=(f"Map {self.id!r} (occupancy grid): log odds"
                       f"{f' at the end of {phase}' if phase else ''}"),
                outlines=outlines,
                movements=shown,
                verdict=outcome.verdict,
            )
        return {}
