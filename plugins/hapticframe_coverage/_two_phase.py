"""The dissertation's two-phase haptic exploration strategy (section 3.4.4).

Phase 1 rakes parallel coverage lines in binary-search order until a movement interacts
with the buried object, then rakes the same line from the opposite boundary. Phase 2 then,
for each movement: estimates the centroid from the map, shrinks the search region around
it, draws a sweep angle far from those used before, and rakes the candidate line that
maximises Eq. 3.9, until the map is certain enough inside the region or a cap is reached.

Readings of the dissertation chosen here (all configurable):

- *Phase 1 ends with the reverse pass*, whether or not that pass interacts (the object may
  have moved); both passes count as phase-1 movements. If every line is raked without an
  interaction the search ends: nothing is buried within reach.
- *Shrinking by 25 %* multiplies each side of the current region by 0.75 before every
  phase-2 movement, centred on the centroid estimate and kept inside the search region,
  never below ``min_region_size_m``.
- *Centroid*: the occupancy-weighted centroid of the map's blob above 0.6 closest to the
  interaction points (``blob_centroid``), or the mean of the interaction points when no cell
  reaches 0.6.
- *Eq. 3.9* sums over points every ``score_step_m`` along each candidate (so it is a path
  integral), with the squared distance divided by the squared diagonal of the current region.
  With the published w3 = −1 the distance term *attracts* paths towards the centroid estimate
  although the text says it pushes them away; the sign is a config value.
- *Stopping*: "std within S fell below a percentage λ of the size of S" is read as the area
  of S whose std exceeds ``uncertain_std`` being less than λ of the area of S (or, with
  ``stop_rule = "mean-std"``, the mean std over S being less than λ · 0.5). It is checked
  before each phase-2 movement once ``min_phase2_movements`` were made.
- *Sweep angles* are drawn uniformly from the directions at least 30° (modulo 180°) from all
  angles used before, the phase-1 angle included; once six directions are used no angle
  fits, and the oldest are forgotten until one does.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hapticframe.geometry import blob_centroid, sample_grid
from hapticframe.kinds import BuildContext, ExploratoryMovement, Map, MovementResult

from ._base import LinePlanner
from ._config import TwoPhaseCoverageConfig
from ._functional import (
    Bounds,
    binary_search_order,
    line_scores,
    parallel_lines,
    points_along,
    sample_sweep_angle_deg,
    shrink_bounds,
    uncertainty_fraction,
)

__all__ = ["TwoPhaseCoverage"]

FloatArray = NDArray[np.float64]


class TwoPhaseCoverage(LinePlanner):
    """Binary-search coverage, then next-best lines chosen on the occupancy map.

    Parameters
    ----------
    config : TwoPhaseCoverageConfig
    context : BuildContext
        ``inputs`` should hold the occupancy map to read (``config.map_id`` or the first
        map); without one, phase 2 relies on the interaction points and the movement caps.
    """

    config: TwoPhaseCoverageConfig

    def __init__(self, config: TwoPhaseCoverageConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        if config.map_id is not None:
            chosen = context.inputs.get(config.map_id)
            if not isinstance(chosen, Map):
                raise ValueError(f"map_id {config.map_id!r} does not name an input map")
            self._map: Map | None = chosen
        else:
            self._map = self._maps[0] if self._maps else None
        self.reset()

    def reset(self) -> None:
        """Start the search again from phase 1."""
        super().reset()
        starts, ends = parallel_lines(
            self.search_bounds, self.phase1_angle_deg, self.config.line_spacing_m
        )
        self.phase1_lines: tuple[FloatArray, FloatArray] = (starts, ends)
        self._queue = binary_search_order(len(starts))
        self._phase = "phase1"
        self._reverse_of: ExploratoryMovement | None = None
        self._awaiting_reverse = False
        self.used_angles_deg: list[float] = [self.phase1_angle_deg]
        self.current_bounds: Bounds = self.search_bounds
        self.interaction_points: list[FloatArray] = []
        self.centroid_m: FloatArray | None = None
        self.last_uncertainty: float | None = None
        self._proposed = 0
        self._phase2_proposed = 0

    @property
    def phase(self) -> str:
        """``"phase1"``, ``"phase2"`` or ``"done"``."""
        return self._phase

    # --- the loop ------------------------------------------------------------------------------

    def propose(self) -> ExploratoryMovement | None:
        """The next movement, or None once the search is complete."""
        if self._phase == "done":
            return None
        if self._proposed >= self.max_movements:
            return self._finish()
        movement = self._propose_phase1() if self._phase == "phase1" else None
        if movement is None and self._phase == "phase2":
            movement = self._propose_phase2()
        if movement is not None:
            self._proposed += 1
        return movement

    def on_movement_end(self, result: MovementResult) -> None:
        """Record interactions; they drive the switch from phase 1 to phase 2."""
        super().on_movement_end(result)
        interacted = self.is_interaction(result)
        if interacted:
            self.interaction_points.append(self.stop_point(result))
        if self._phase != "phase1":
            return
        if self._awaiting_reverse:
            self._awaiting_reverse = False
            self._phase = "phase2"
        elif interacted:
            self._reverse_of = result.movement

    def _finish(self) -> None:
        self._phase = "done"
        return None

    # --- phase 1 -------------------------------------------------------------------------------

    def _propose_phase1(self) -> ExploratoryMovement | None:
        if self._reverse_of is not None:
            first = self._reverse_of
            self._reverse_of = None
            self._awaiting_reverse = True
            return self.make_movement(
                first.end_m, first.start_m, "phase1", f"phase 1: reverse of {first.label}"
            )
        if not self._queue:
            return self._finish()  # every line raked without an interaction
        index = self._queue.pop(0)
        starts, ends = self.phase1_lines
        return self.make_movement(
            starts[index], ends[index], "phase1", f"line {index + 1}/{len(starts)}"
        )

    # --- phase 2 -------------------------------------------------------------------------------

    def _propose_phase2(self) -> ExploratoryMovement | None:
        c = self.config
        if self._phase2_proposed >= c.max_phase2_movements:
            return self._finish()
        self.centroid_m = self._estimate_centroid()
        self.current_bounds = shrink_bounds(
            self.current_bounds,
            self.centroid_m,
            1.0 - c.region_shrink,
            self.search_bounds,
            c.min_region_size_m,
        )
        self._regions.append(self.current_bounds)
        if self._map is not None:
            _, _, grid_points = sample_grid(self.current_bounds, c.grid_spacing_m)
            std = self._map.query(grid_points).std
            self.last_uncertainty = uncertainty_fraction(std, c.stop_rule, c.uncertain_std)
            if (
                self._phase2_proposed >= c.min_phase2_movements
                and self.last_uncertainty < c.stop_fraction
            ):
                return self._finish()
        angle = sample_sweep_angle_deg(
            self.context.rng, self.used_angles_deg, c.min_sweep_separation_deg
        )
        starts, ends = parallel_lines(self.current_bounds, angle, c.phase2_line_spacing_m)
        if len(starts) == 0:  # cannot happen for a region of positive size; be safe
            return self._finish()
        best, mean_at_ends = self._best_candidate(starts, ends)
        self.used_angles_deg.append(angle)
        start, end = starts[best], ends[best]
        low_start = mean_at_ends[1] < mean_at_ends[0] - 1e-6
        tie = abs(mean_at_ends[1] - mean_at_ends[0]) <= 1e-6
        if low_start or (tie and self.context.rng.random() < 0.5):
            start, end = end, start  # begin in granular material, not inside the object
        self._phase2_proposed += 1
        return self.make_movement(
            start, end, "phase2",
            f"phase 2: sweep {angle:.0f} deg, line {best + 1}/{len(starts)}",
        )

    def _best_candidate(self, starts: FloatArray, ends: FloatArray) -> tuple[int, FloatArray]:
        """Index of the line maximising Eq. 3.9 and the map's mean at its (start, end)."""
        c = self.config
        points, index = points_along(starts, ends, c.score_step_m)
        if self._map is not None:
            estimate = self._map.query(points)
            mean, std = estimate.mean, estimate.std
        else:  # no map: only the distance term discriminates
            mean, std = np.full(len(points), 0.5), np.zeros(len(points))
        x0, x1, y0, y1 = self.current_bounds
        scores = line_scores(
            mean, std, points, index, self.centroid_m,
            (c.occupancy_weight, c.uncertainty_weight, c.distance_weight),
            math.hypot(x1 - x0, y1 - y0), len(starts),
        )
        best = int(np.argmax(scores))
        on_best = np.flatnonzero(index == best)
        return best, mean[[on_best[0], on_best[-1]]]

    def _estimate_centroid(self) -> FloatArray:
        near = np.mean(self.interaction_points, axis=0) if self.interaction_points else None
        centre = None
        grid = self._map_grid()
        if grid is not None:
            xs, ys, mean = grid
            centre = blob_centroid(xs, ys, mean, self.config.centroid_level, near_m=near)
        if centre is None:
            if near is not None:
                centre = near
            elif self.centroid_m is not None:
                centre = self.centroid_m
            else:
                x0, x1, y0, y1 = self.current_bounds
                centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
        return np.asarray(centre, dtype=np.float64)

    def _map_grid(self) -> tuple[FloatArray, FloatArray, FloatArray] | None:
        """The map's mean on a grid: its own ``probability_grid`` if it has one, else queries."""
        if self._map is None:
            return None
        spacing = self.config.grid_spacing_m
        own_grid = getattr(self._map, "probability_grid", None)
        if callable(own_grid):
            xs, ys, mean, _ = own_grid(spacing)
            xs, ys = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
            mean = np.asarray(mean, dtype=np.float64)
            if mean.size == xs.size * ys.size:
                return xs, ys, mean.reshape(ys.size, xs.size)
        xs, ys, points = sample_grid(self.search_bounds, spacing)
        mean = self._map.query(points).mean.reshape(ys.size, xs.size)
        return xs, ys, mean
