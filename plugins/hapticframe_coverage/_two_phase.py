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
  interaction points (``blob_centroid``); when no cell reaches 0.6, the blob at 0.5, 0.4 or
  0.3, and only then the mean of the interaction points.
- *Eq. 3.9* sums over points every ``score_step_m`` along each candidate (so it is a path
  integral), with the squared distance divided by the squared diagonal of the current region.
  With the published w3 = −1 the distance term *attracts* paths towards the centroid estimate
  although the text says it pushes them away; the sign is a config value.
- *Stopping*: "std within S fell below a percentage λ of the size of S" is read as the area
  of S whose std exceeds ``uncertain_std`` being less than λ of the area of S (or, with
  ``stop_rule = "mean-std"``, the mean std over S being less than λ · 0.5). It is checked
  before each phase-2 movement once ``min_phase2_movements`` were made.
- *Every object* (``max_objects``, default 1 = the dissertation): once an object's phase 2
  stops, its outline (the map's ``centroid_level`` curve around the estimate, else a disc
  through its interaction points) joins the found objects; the phase-1 lines not yet raked
  are raked in the parts lying more than ``found_margin_m`` from every found object, and
  the next interaction elsewhere starts a new phase 1 reverse pass and phase 2. Phase-2
  lines are cut short before a found object. The search ends when ``max_objects`` were
  localised or the phase-1 lines are exhausted.
- *A reverse pass that meets nothing* (``reverse_confirms``, off by default): the first
  pass's interaction was a false alarm; it is dropped and phase 1 goes on, instead of
  phase 2 circling a blob that is not there.
- *Nothing met* (``phase1_second_pass``, off by default): the lines midway between the
  first ones (``between``) or at right angles to them (``across``) are raked before the
  search gives up.
- *Fewer touches* (issue 19 §6, both off by default): ``phase1_reverse: false`` skips the
  reverse pass; ``stop_short_m`` ends each phase-2 movement, once the object was met
  ``stop_short_after`` times, that far before the outline estimate, and such a movement
  counts as an approach from its side for the angular-gap rule. docs/benchmarks.md
  ("Fewer movements, fewer touches") measures both: fewer touches, a coarser outline.
- *Sweep angles* are drawn uniformly from the directions at least 30° (modulo 180°) from all
  angles used before, the phase-1 angle included; once six directions are used no angle
  fits, and the oldest are forgotten until one does.

Defaults that differ from the dissertation, and why
---------------------------------------------------
The reading above is one configuration away (``line_spacing_m: 0.035``, ``phase1_order:
binary``, ``phase2_region_size_m: null``, ``min_region_size_m: 0.1``, ``sweep_rule:
random``, ``stop_rule: uncertain-area``, ``met_from: heading``). The defaults were tuned on
the ``search`` benchmark's seeds 100 and above (never 0-24) against Table 3.2's movement
counts (7.2 and 7.0 in all) and accuracy:

- *Phase 1: 10 cm lines, the two outermost last.* At the full depth the classifier detects
  an object whose outline passes within about 2.5 cm of the fingertip's path, so lines
  10 cm apart always meet an 8 cm circle or a 9 x 5 cm ellipse; 3.5 cm lines only add
  movements. A buried object is less often centred near the region's edges, so the lines
  half a spacing from them come last (3.5 phase-1 movements on average, reverse included).
- *Phase 2 in a 32 cm square around the estimate* (then shrinking by 25 % to at least
  26 cm): lines start 13-16 cm from the object, outside its failure zone, instead of up to
  the region's far side (shorter movements, same information).
- *Widest-gap approach* (``sweep_rule: widest-gap``). Each interacting movement met the
  object from one side, taken as the direction from the centroid estimate to where it
  stopped (``met_from: stop-point``: a phase-1 line passing beside the centre met it from
  that side). The next line is aimed through the estimate from the direction farthest from
  every side met so far (among those keeping the 30° sweep separation and starting at least
  ``min_start_distance_m`` from the estimate, inside the region), and raked from that side.
  Random angles with Eq. 3.9's low-occupancy start met the object from the same side
  repeatedly.
- *Angular-gap stopping* (``stop_rule: angular-gap``): stop once every direction the object
  can be approached from lies within 55° of a side met (``max_gap_deg: 110``). The λ rule
  on the map's std did not separate "outline known" from "outline guessed" on the BHM's
  std (which stays high wherever no movement passed, e.g. far outside the object) and ran
  to the 12-movement cap in most trials; this rule needs 2-4 phase-2 movements.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hapticframe.geometry import blob_centroid, main_outline, sample_grid
from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    GridQueryable,
    Map,
    MovementResult,
)

from ._base import LinePlanner
from ._config import TwoPhaseCoverageConfig
from ._functional import (
    Bounds,
    allowed_sweep_mask,
    bearing_gap_scores_deg,
    binary_search_order,
    free_runs,
    inside_or_near,
    line_scores,
    outer_last_order,
    parallel_lines,
    points_along,
    ray_exit_distance,
    sample_sweep_angle_deg,
    shrink_bounds,
    uncertainty_fraction,
)

__all__ = ["TwoPhaseCoverage"]

#: Lower occupancy levels tried, in turn, when no blob reaches ``centroid_level``.
_FALLBACK_LEVELS = (0.5, 0.4, 0.3)

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
        self._second_pass = False
        self._lay_phase1_lines(self.phase1_angle_deg)
        self._phase = "phase1"
        self._reverse_of: ExploratoryMovement | None = None
        self._awaiting_reverse = False
        self._forward_points = 0
        self.used_angles_deg: list[float] = [self.phase1_angle_deg]
        self.current_bounds: Bounds = self.search_bounds
        self.interaction_points: list[FloatArray] = []
        self.met_from_deg: list[float] = []
        #: Stop points and approach directions of movements that stopped short and stayed free.
        self.probe_points: list[FloatArray] = []
        self.probe_from_deg: list[float] = []
        self._probe_pending = False
        self.centroid_m: FloatArray | None = None
        self.last_uncertainty: float | None = None
        self._proposed = 0
        self._phase2_proposed = 0
        #: Outlines and centroid estimates of the objects localised so far.
        self.found_outlines: list[FloatArray] = []
        self.found_centroids: list[FloatArray] = []
        self._segments: list[tuple[FloatArray, FloatArray, str]] = []

    def _lay_phase1_lines(self, angle_deg: float, *, between: bool = False) -> None:
        """Phase 1's lines at ``angle_deg`` (``between``: midway between those) and the
        order they are raked in."""
        starts, ends = parallel_lines(self.search_bounds, angle_deg, self.config.line_spacing_m,
                                      between=between)
        self.phase1_lines: tuple[FloatArray, FloatArray] = (starts, ends)
        if self.config.phase1_order == "binary":
            self._queue = binary_search_order(len(starts))
        else:
            self._queue = outer_last_order(len(starts))

    def _start_next_object(self) -> None:
        """Forget the per-object state of phase 2; phase 1 resumes its queue."""
        self._phase = "phase1"
        self._reverse_of = None
        self._awaiting_reverse = False
        self.used_angles_deg = [self.phase1_angle_deg]
        self.current_bounds = self.search_bounds
        self.interaction_points = []
        self.met_from_deg = []
        self.probe_points = []
        self.probe_from_deg = []
        self._probe_pending = False
        self.centroid_m = None
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
            self._finish()
            return None
        movement = None
        # Each step either proposes, finishes, or (an object localised) returns to phase 1.
        while movement is None and self._phase != "done":
            if self._phase == "phase1":
                movement = self._propose_phase1()
            else:
                movement = self._propose_phase2()
        if movement is not None:
            self._proposed += 1
        return movement

    def on_movement_end(self, result: MovementResult) -> None:
        """Record interactions; they drive the switch from phase 1 to phase 2."""
        super().on_movement_end(result)
        interacted = self.is_interaction(result)
        if interacted and self.found_outlines and inside_or_near(
                self.stop_point(result), self.found_outlines, 2 * self.config.found_margin_m
        )[0]:
            interacted = False  # met an object found before: no news
        if interacted:
            self.interaction_points.append(self.stop_point(result))
            # Seen from the object, it was met from where the movement came from.
            self.met_from_deg.append((math.degrees(result.movement.heading_rad) + 180.0) % 360.0)
        elif self._probe_pending:
            # Stopped short and stayed free: that side was approached without a touch.
            self.probe_points.append(self.stop_point(result))
            self.probe_from_deg.append(
                (math.degrees(result.movement.heading_rad) + 180.0) % 360.0)
        self._probe_pending = False
        if self._phase != "phase1":
            return
        if self._awaiting_reverse:
            self._awaiting_reverse = False
            if interacted or not self.config.reverse_confirms:
                self._phase = "phase2"
            else:
                # The line met nothing from its far end: the first pass's report was a
                # false alarm (an object on the line is met from both ends), so its
                # interaction does not steer phase 2; phase 1 goes on.
                del self.interaction_points[self._forward_points:]
                del self.met_from_deg[self._forward_points:]
        elif interacted and self.config.phase1_reverse:
            self._reverse_of = result.movement
            self._forward_points = len(self.interaction_points) - 1
        elif interacted:
            self._phase = "phase2"

    def _finish(self) -> None:
        self._phase = "done"

    def _object_done(self) -> None:
        """Phase 2 of the current object stopped: keep it, then finish or look for more."""
        centre = self.centroid_m if self.centroid_m is not None else self._estimate_centroid()
        self.found_centroids.append(np.asarray(centre, dtype=np.float64))
        limit = self.config.max_objects
        if limit is not None and len(self.found_centroids) >= limit:
            self._finish()  # no outline needed: nothing more is raked
            return
        self.found_outlines.append(self._outline_estimate(centre, (self.config.centroid_level,)))
        self._start_next_object()

    def _free_parts(self, start: FloatArray, end: FloatArray
                    ) -> list[tuple[FloatArray, FloatArray]]:
        """The parts of a line away from every found object (the whole line before any)."""
        if not self.found_outlines:
            return [(start, end)]
        c = self.config
        count = max(2, math.ceil(float(np.linalg.norm(end - start)) / c.score_step_m) + 1)
        points = start + np.linspace(0.0, 1.0, count)[:, None] * (end - start)
        blocked = inside_or_near(points, self.found_outlines, c.found_margin_m)
        return free_runs(start, end, blocked, c.min_segment_m)

    # --- phase 1 -------------------------------------------------------------------------------

    def _propose_phase1(self) -> ExploratoryMovement | None:
        if self._reverse_of is not None:
            first = self._reverse_of
            self._reverse_of = None
            self._awaiting_reverse = True
            return self.make_movement(
                first.end_m, first.start_m, "phase1", f"phase 1: reverse of {first.label}"
            )
        starts, ends = self.phase1_lines
        while not self._segments:
            second = self.config.phase1_second_pass
            if not self._queue and second != "none" and not self._second_pass:
                # Nothing met: the object may lie between two lines.
                self._second_pass = True
                if second == "across":
                    angle = (self.phase1_angle_deg + 90.0) % 180.0
                    self._lay_phase1_lines(angle)
                    self.used_angles_deg.append(angle)
                else:
                    self._lay_phase1_lines(self.phase1_angle_deg, between=True)
                starts, ends = self.phase1_lines
            if not self._queue:
                self._finish()  # every line raked without an interaction
                return None
            index = self._queue.pop(0)
            label = f"line {index + 1}/{len(starts)}"
            parts = self._free_parts(starts[index], ends[index])
            self._segments = [
                (a, b, label if len(parts) == 1 else f"{label} part {k + 1}/{len(parts)}")
                for k, (a, b) in enumerate(parts)
            ]
        start, end, label = self._segments.pop(0)
        return self.make_movement(start, end, "phase1", label)

    # --- phase 2 -------------------------------------------------------------------------------

    def _propose_phase2(self) -> ExploratoryMovement | None:
        c = self.config
        if self._phase2_proposed >= c.max_phase2_movements:
            self._object_done()
            return None
        self.centroid_m = self._estimate_centroid()
        if self._phase2_proposed == 0 and c.phase2_region_size_m is not None:
            # The first phase-2 region: a square around the estimate, not the whole area.
            side = max(c.phase2_region_size_m, c.min_region_size_m)
            x0, x1, y0, y1 = self.search_bounds
            half = min(side / 2, (x1 - x0) / 2), min(side / 2, (y1 - y0) / 2)
            self.current_bounds = shrink_bounds(
                (self.centroid_m[0] - half[0], self.centroid_m[0] + half[0],
                 self.centroid_m[1] - half[1], self.centroid_m[1] + half[1]),
                self.centroid_m, 1.0, self.search_bounds, c.min_region_size_m,
            )
        else:
            self.current_bounds = shrink_bounds(
                self.current_bounds,
                self.centroid_m,
                1.0 - c.region_shrink,
                self.search_bounds,
                c.min_region_size_m,
            )
        self._regions.append(self.current_bounds)
        if self._should_stop():
            self._object_done()
            return None
        if c.sweep_rule == "random":
            angle = sample_sweep_angle_deg(
                self.context.rng, self.used_angles_deg, c.min_sweep_separation_deg
            )
            bearing = None
        else:
            bearing = self._widest_gap_bearing()
            angle = bearing % 180.0
        starts, ends = parallel_lines(self.current_bounds, angle, c.phase2_line_spacing_m)
        if len(starts) == 0:  # cannot happen for a region of positive size; be safe
            self._finish()
            return None
        best, mean_at_ends = self._best_candidate(starts, ends)
        self.used_angles_deg.append(angle)
        start, end = starts[best], ends[best]
        if bearing is not None:
            # Come from the chosen side: the start lies towards the bearing.
            towards = np.array([math.cos(math.radians(bearing)), math.sin(math.radians(bearing))])
            if float((start - end) @ towards) < 0:
                start, end = end, start
        else:
            low_start = mean_at_ends[1] < mean_at_ends[0] - 1e-6
            tie = abs(mean_at_ends[1] - mean_at_ends[0]) <= 1e-6
            if low_start or (tie and self.context.rng.random() < 0.5):
                start, end = end, start  # begin in granular material, not inside the object
        if self.found_outlines:
            # Stop short of the objects found before (the first free part from the start).
            parts = self._free_parts(start, end)
            if not parts or float(np.linalg.norm(parts[0][0] - start)) > c.score_step_m:
                self._object_done()  # no way in from here that misses a found object
                return None
            start, end = parts[0]
        label = f"phase 2: sweep {angle:.0f} deg, line {best + 1}/{len(starts)}"
        if c.stop_short_m is not None and len(self.interaction_points) >= c.stop_short_after:
            short = self._stop_short(start, end)
            if short is not None:
                start, end = short
                self._probe_pending = True
                label += ", stopping short"
        self._phase2_proposed += 1
        return self.make_movement(start, end, "phase2", label)

    def _outline_estimate(self, centre: FloatArray, levels: tuple[float, ...]) -> FloatArray:
        """The object's outline: the map's level curve around ``centre`` at the first of
        ``levels`` that has one, else a disc through the interaction points (3 cm at least)."""
        grid = self._map_grid()
        if grid is not None:
            for level in levels:
                outline = main_outline(*grid, level, near_m=centre)
                # A curve not around the estimate is another blob's, not this object's.
                if outline is not None and inside_or_near(centre, [outline], 0.0)[0]:
                    return np.asarray(outline, dtype=np.float64)
        reach = max([0.03, *(float(np.linalg.norm(p - centre)) for p in self.interaction_points)])
        angles = np.linspace(0.0, 2 * math.pi, 32, endpoint=False)
        return centre + reach * np.column_stack([np.cos(angles), np.sin(angles)])

    def _stop_short(self, start: FloatArray, end: FloatArray
                    ) -> tuple[FloatArray, FloatArray] | None:
        """The part of a line that stays ``stop_short_m`` from the outline estimate (the
        ``centroid_level`` curve, else a lower one as for the centroid, else a disc through
        the interaction points), at least ``min_segment_m`` long (its start moved back
        along the line when needed); None when the line never comes that near or no such
        part fits in the search region (it then rakes through)."""
        c = self.config
        assert c.stop_short_m is not None  # the caller checks
        levels = (c.centroid_level, *(v for v in _FALLBACK_LEVELS if v < c.centroid_level))
        outline = self._outline_estimate(self._known_centroid(), levels)
        count = max(2, math.ceil(float(np.linalg.norm(end - start)) / c.score_step_m) + 1)
        points = start + np.linspace(0.0, 1.0, count)[:, None] * (end - start)
        near = inside_or_near(points, [outline], c.stop_short_m)
        if not near.any():
            return None
        first = int(np.argmax(near))
        stop = np.asarray(points[max(first - 1, 0)], dtype=np.float64)
        if first > 0 and float(np.linalg.norm(stop - start)) >= c.min_segment_m:
            return start, stop
        # Too short from the region's edge (a small phase-2 region, a wide margin): start
        # farther back along the same line, inside the search region.
        u = (end - start) / float(np.linalg.norm(end - start))
        back = math.degrees(math.atan2(-u[1], -u[0]))
        room = float(ray_exit_distance(stop, [back], self.search_bounds)[0])
        if room < c.min_segment_m:
            return None
        if inside_or_near(stop, [outline], c.stop_short_m - c.score_step_m)[0]:
            return None  # the line's start itself is too near the object
        return stop - c.min_segment_m * u, stop

    def phase_metrics(self) -> dict[str, int]:
        """Movements per phase and, when several objects are sought, how many were found."""
        out = super().phase_metrics()
        if self.config.max_objects != 1:
            out["objects_localised"] = len(self.found_centroids)
        return out

    def _should_stop(self) -> bool:
        """The stopping rule, consulted before each phase-2 movement (section 3.4.4)."""
        c = self.config
        if c.stop_rule == "angular-gap":
            gap = self._open_gap_deg()
            self.last_uncertainty = gap / 360.0
            return self._phase2_proposed >= c.min_phase2_movements and gap <= c.max_gap_deg
        if self._map is None:
            return False
        _, _, grid_points = sample_grid(self.current_bounds, c.grid_spacing_m)
        std = self._map.query(grid_points).std
        self.last_uncertainty = uncertainty_fraction(std, c.stop_rule, c.uncertain_std)
        return (
            self._phase2_proposed >= c.min_phase2_movements
            and self.last_uncertainty < c.stop_fraction
        )

    def _met_from(self) -> list[float]:
        """Directions (degrees) the object was met from, seen from the centroid estimate."""
        headings = [*self.met_from_deg, *self.probe_from_deg]
        if self.config.met_from == "heading" or self.centroid_m is None:
            return headings
        out = []
        stops = [*self.interaction_points, *self.probe_points]
        for stop, heading in zip(stops, headings, strict=True):
            offset = np.asarray(stop) - self.centroid_m
            if float(np.hypot(*offset)) < 1e-9:
                out.append(heading)
            else:
                out.append(math.degrees(math.atan2(offset[1], offset[0])) % 360.0)
        return out

    def _known_centroid(self) -> FloatArray:
        """The centroid estimate, which phase 2 sets before anything that needs it runs."""
        if self.centroid_m is None:
            raise RuntimeError("no centroid estimate: phase 2 has not started")
        return self.centroid_m

    def _open_gap_deg(self) -> float:
        """Twice the angular distance from the met-from directions to the farthest direction
        the object can still be approached from (one whose line would start at least
        ``min_start_distance_m`` from the centroid estimate inside the search region).

        With the object met from every side this is the widest gap between met-from
        directions; directions blocked by the region's edge do not count as open.
        """
        c = self.config
        candidates = np.arange(0.0, 360.0, c.gap_step_deg)
        room = ray_exit_distance(self._known_centroid(), candidates, self.search_bounds)
        open_ = room >= c.min_start_distance_m
        if not open_.any():
            return 0.0
        return 2.0 * float(bearing_gap_scores_deg(candidates[open_], self._met_from()).max())

    def _widest_gap_bearing(self) -> float:
        """The direction (degrees, seen from the centroid estimate) to approach from next.

        Among directions on a ``gap_step_deg`` grid whose line keeps the sweep separation,
        preferring those whose start lies at least ``min_start_distance_m`` from the
        estimate, the one farthest from every direction the object was already met from;
        ties are broken with the planner's generator.
        """
        c = self.config
        candidates = np.arange(0.0, 360.0, c.gap_step_deg)
        allowed = allowed_sweep_mask(candidates, self.used_angles_deg, c.min_sweep_separation_deg)
        room = ray_exit_distance(self._known_centroid(), candidates, self.current_bounds)
        roomy = allowed & (room >= c.min_start_distance_m)
        pool = roomy if roomy.any() else allowed
        scores = np.where(pool, bearing_gap_scores_deg(candidates, self._met_from()), -np.inf)
        best = np.flatnonzero(scores >= scores.max() - 1e-9)
        return float(candidates[best[int(self.context.rng.integers(best.size))]])

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
            mean, std, points, index, self._known_centroid(),
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
            # Nothing at the outline level (e.g. a movement swept the estimate away): the
            # strongest remaining evidence, at lower levels, still beats the bare mean of
            # the interaction points.
            for level in (self.config.centroid_level, *_FALLBACK_LEVELS):
                if level > self.config.centroid_level:
                    continue
                centre = blob_centroid(xs, ys, mean, level, near_m=near)
                if centre is not None:
                    break
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
        """The map's mean on a grid: its own when it is
        :class:`~hapticframe.kinds.GridQueryable`, else from queries."""
        if self._map is None:
            return None
        spacing = self.config.grid_spacing_m
        if isinstance(self._map, GridQueryable):
            xs, ys, mean, _ = self._map.probability_grid(spacing)
            xs, ys = np.asarray(xs, dtype=np.float64), np.asarray(ys, dtype=np.float64)
            mean = np.asarray(mean, dtype=np.float64)
            if mean.size == xs.size * ys.size:
                return xs, ys, mean.reshape(ys.size, xs.size)
        xs, ys, points = sample_grid(self.search_bounds, spacing)
        mean = self._map.query(points).mean.reshape(ys.size, xs.size)
        return xs, ys, mean
