"""The failure-zone kernel sensor model: located class probabilities become map observations.

For each emitted sample the sector ahead of the fingertip (range r, half-angle η about the
direction of motion, Eq. 3.2) is sampled on a polar grid and every point gets the occupancy
target of the three-state kernel mixture (Eqs. 3.3-3.4). The parameters follow one of three
schedules (see :class:`~hapticframe_failure_zone.FailureZoneConfig`) that change only between
movements, in :meth:`FailureZoneKernel.on_movement_end`.

Readings of the dissertation's loose ends, chosen here:

- *Pairwise interactions.* n in Table 3.1 counts pairs: a movement *interacts* when it was
  halted for an interaction or its final class maps to jamming or contact, and
  ``n = interacting_movements // 2`` (the first pair is the phase-1 approach from both
  sides). The depth schedule, in contrast, shrinks after *each* interacting movement.
- *Empirical range.* Table 3.1 gives γ_r, not r; the sector reaches r = sqrt(ln 2/γ_r), where
  the kernel halves (7.06 cm at n = 0, matching the 7.1 cm rupture distance).
- *Analytic side angle.* asin's argument exceeds 1 for the dissertation's own numbers, so it is
  clipped (η = 90°, a half disc) and a :class:`FailureZoneAngleWarning` is issued once per
  instance; η is never NaN.
- *Travel spacing.* Sectors overlap heavily at the sampling rate of a force sensor, so a sample
  is emitted when the fingertip's path length since the movement began crosses a multiple of
  ``observation_spacing_m``, and always for the first sample of a movement and for any sample
  whose state differs from the previous one (the first jamming or contact sample). The path
  length and the previous state are carried across calls, so observing rows one at a time
  equals observing them at once.

Defaults that differ from the dissertation, and why
---------------------------------------------------
The dissertation's model is one configuration away (``schedule: empirical``,
``free_range_scale: 1``, ``free_gamma_scale: 1``, ``jamming_shape: sector`` with the sector
scales at their defaults 0, 1, 1, ``first_pair_weight: 1``, ``sector_spacing_m`` and
``observation_spacing_m`` 0.01). The defaults are calibrated against what the
force-rate classifier actually reports in the ``sandbox`` simulator (its physics
unchanged): measured on 1,000 simulated straight approaches to circles and ellipses at the
four depths of Table 3.1 (where the classifier stops, and how often each point around the
fingertip is occupied when it stops or while it reports free movement), then tuned by
replaying searches of the ``search`` benchmark on seeds 100 and above (never seeds 0-24):

- *Range from the measured depth* (``schedule: hybrid``). Table 3.1's γ_r shrinks once per
  *pair* of interactions, while the soil (and so the rupture distance) shrinks after *every*
  interacting movement; the robot reports its raking depth, so r = d (cot α + cot β) is used
  directly (7.2, 5.5, 4.7, 4.3 cm, the rupture distances Table 3.1 lists). η keeps Table
  3.1's line 50 + 7n, capped at 90° (:func:`hapticframe_granular.side_crescent_angle`).
- *Free movement reaches 0.85 r with targets near 0* (``free_range_scale: 0.85``,
  ``free_gamma_scale: 0.04``). The classifier halts a movement when the object is about
  0.7 r ahead (mean 0.71 r, sd 0.08 r at 4.4 cm depth; 0.58 r at 2.65 cm), so a free sample
  proves the sector empty only up to roughly that distance, not to r. Over those
  approaches an object lay within 0.8 r of a free-classified sample in under 2 % of sector
  points, so targets of 0 to 0.02 there are calibrated, where Eq. 3.3 would give 0 to 0.5
  and push the object itself towards "free" (the lead's observation (1)).
- *Jamming speaks about a disc* (``jamming_shape: disc``, near edge 0.45 r ahead, radius
  3.6 cm, targets from the jamming kernel of Eq. 3.3). The occupied part of Eq. 3.2's fan
  (±50°, up to r) is wider than any object met head-on: for an 8 cm circle 5.4 cm ahead the
  object spans ±25°, and P(occupied | jamming) fell to 0.3 at ±40° in the simulated
  approaches, so the fan's sides painted "ears" beside the object. A convex object met
  straight ahead curves away from the point met, which a disc tangent there describes;
  the disc starts short of the detection distance so that the free sectors, which end just
  before it, set where the map crosses 0.6.
- *The first pair counts half* (``first_pair_weight: 0.5``). The phase-1 lines are not
  aimed at the object: they pass it up to 5 cm off centre, where the object is met at the
  side of the failure zone and the disc straight ahead is misplaced. Later (aimed)
  interactions then outweigh them. Like Table 3.1's γ_r and η, this depends on n.
- *Fewer points*: 1.5 cm polar spacing every 2 cm of travel (Table 3.1's 5 cm hinges need no
  finer sampling) gives about 2,500 observations per search instead of 8,000-22,000.

Single samples that emit nothing (nearly every tick of a closed loop) are answered in plain
floats without building arrays (:meth:`FailureZoneKernel._quiet_single_row`).
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe import atomic_write
from hapticframe.kinds import (
    BuildContext,
    CalibrationRecording,
    LocatedMeasurement,
    MovementResult,
    Observations,
    SensorModel,
)
from hapticframe_granular import (
    arthur_angle,
    rupture_distance,
    side_crescent_angle,
    side_crescent_angle_analytic,
)

from ._calibration import FailureZoneFit, fit_failure_zone
from ._config import FailureZoneConfig
from ._functional import (
    STATES,
    FailureZoneAngleWarning,
    depth_schedule,
    disc_offsets,
    empirical_gamma,
    kernel_targets,
    mixture_targets,
    range_from_gamma,
    rupture_gamma,
    sector_offsets,
    state_coverage,
)

__all__ = ["FailureZoneKernel"]

FloatArray = NDArray[np.float64]

#: The answer of a sample that emits nothing (records are immutable, so one is enough).
_NOTHING = Observations.empty()

#: Entries kept in each cache of sector geometry before it is cleared (depths vary little).
_CACHE_SIZE = 64

#: Shear-band angle (rad) when neither the config nor a scene gives one (φ = 42°, ψ = 12°).
_DEFAULT_SHEAR_BAND_RAD = arthur_angle(math.radians(42.0), math.radians(12.0))


class FailureZoneKernel(SensorModel):
    """Kernel-based sensor model of the granular failure zone (dissertation section 3.4.3.1).

    Parameters
    ----------
    config : FailureZoneConfig
    context : BuildContext
        ``context.scene.material`` supplies the shear-band angle when the config does not.
    """

    #: The file :meth:`save` writes into an artifact folder.
    ARTIFACT = "failure_zone_fit.json"

    def __init__(self, config: FailureZoneConfig, context: BuildContext) -> None:
        if config.model_dir is not None:
            config = _updated(config, _read_fit(Path(config.model_dir))["config"])
        super().__init__(config, context)
        self._fit: FailureZoneFit | None = None
        if config.shear_band_angle_deg is not None:
            beta = math.radians(config.shear_band_angle_deg)
        elif context.scene is not None:
            material = context.scene.material
            beta = arthur_angle(
                math.radians(material.friction_angle_deg),
                math.radians(material.dilation_angle_deg),
            )
        else:
            beta = _DEFAULT_SHEAR_BAND_RAD
        if not 0.0 < beta < math.pi / 2:
            raise ValueError(
                f"shear-band angle must lie in (0, 90) degrees, got {math.degrees(beta)}"
            )
        self.shear_band_angle_rad = beta
        self.rake_angle_rad = math.radians(config.rake_angle_deg)
        self._warned_angle = False
        self._class_cache: dict[tuple[str, ...], FloatArray] = {}
        self._column_cache: dict[tuple[str, ...], list[int]] = {}
        self._sector_cache: dict[tuple[float, float], FloatArray] = {}
        self._target_cache: dict[
            tuple[float, float, int, bool], tuple[FloatArray, FloatArray, FloatArray]
        ] = {}
        self.reset()

    # --- state between movements ------------------------------------------------------------

    def reset(self) -> None:
        """Forget the interaction count and the travel bookkeeping."""
        self.interacting_movements = 0
        self._start_movement()

    def _start_movement(self) -> None:
        self._previous_position: tuple[float, float] | None = None
        self._previous_state = -1
        self._travel_m = 0.0

    @property
    def pair_count(self) -> int:
        """n of Table 3.1: completed pairs of interacting movements."""
        return self.interacting_movements // 2

    def scheduled_depth_m(self) -> float:
        """Raking depth of the depth schedule after the interacting movements so far."""
        c = self.config
        return depth_schedule(
            self.interacting_movements,
            c.initial_depth_m,
            c.depth_decrement_m,
            c.depth_decrement_ratio,
            c.min_depth_m,
        )

    def on_movement_end(self, result: MovementResult) -> None:
        """Count interacting movements; the next movement starts a new travel count."""
        final_state = self.config.class_states.get(result.final_class, "")
        if result.halt_reason == "interaction" or final_state in ("jamming", "contact"):
            self.interacting_movements += 1
        self._start_movement()

    # --- parameters ---------------------------------------------------------------------------

    def parameters(self, depth_m: float = float("nan")) -> tuple[float, float, float]:
        """Sector range (m), kernel bandwidth γ_r (m⁻²) and half-angle η (rad) right now.

        Parameters
        ----------
        depth_m : float
            Measured fingertip depth; used by the analytic and hybrid schedules when finite
            (negative depths count as 0). NaN or infinity falls back to the depth schedule.
        """
        c = self.config
        if c.schedule == "empirical":
            gamma = empirical_gamma(
                self.pair_count, c.empirical_gamma_scale_cm2, c.empirical_gamma_ratio
            )
            reach = float(range_from_gamma(gamma))
            eta = side_crescent_angle(
                self.pair_count,
                base_deg=c.empirical_eta_base_deg,
                step_deg=c.empirical_eta_step_deg,
            )
            return min(max(reach, c.min_range_m), c.max_range_m), gamma, eta
        if c.use_measured_depth and math.isfinite(depth_m):
            depth = max(depth_m, 0.0)
        else:
            depth = self.scheduled_depth_m()
        reach = rupture_distance(depth, self.rake_angle_rad, self.shear_band_angle_rad)
        reach = min(max(reach, c.min_range_m), c.max_range_m)
        if c.schedule == "hybrid":
            eta = side_crescent_angle(
                self.pair_count,
                base_deg=c.empirical_eta_base_deg,
                step_deg=c.empirical_eta_step_deg,
            )
            return reach, float(rupture_gamma(reach)), eta
        eta, argument = side_crescent_angle_analytic(reach, self.rake_angle_rad)
        if argument > 1.0 and not self._warned_angle:
            self._warned_angle = True
            warnings.warn(
                f"failure-zone kernel {self.id!r}: the side-crescent formula gives "
                f"asin({argument:.3g}) at r = {reach * 100:.2f} cm; clipped to "
                f"eta = {math.degrees(eta):.1f} deg",
                FailureZoneAngleWarning,
                stacklevel=2,
            )
        return reach, float(rupture_gamma(reach)), eta

    def state_ranges(self, reach_m: float) -> tuple[FloatArray, FloatArray]:
        """Inner and outer radial bounds of the free, jamming and contact sectors (m)."""
        c = self.config
        outer = np.array([c.free_range_scale, c.jamming_range_scale, 0.0]) * reach_m
        inner = np.array([0.0, c.jamming_inner_scale, 0.0]) * reach_m
        return inner, outer

    # --- observations ---------------------------------------------------------------------------

    def _state_matrix(self, classes: tuple[str, ...]) -> FloatArray:
        """(classes, 3) map from class columns to kernel states (cached per class tuple)."""
        cached = self._class_cache.get(classes)
        if cached is not None:
            return cached
        unknown = [name for name in classes if name not in self.config.class_states]
        if unknown:
            raise ValueError(
                f"failure-zone kernel {self.id!r}: classes {unknown} have no kernel state; "
                f"class_states maps {sorted(self.config.class_states)}"
            )
        to_state = np.zeros((len(classes), 3))
        for column, name in enumerate(classes):
            to_state[column, STATES.index(self.config.class_states[name])] = 1.0
        self._class_cache[classes] = to_state
        return to_state

    def state_probabilities(self, measurement: LocatedMeasurement) -> FloatArray:
        """(n, 3) probabilities of (free, jamming, contact), summed over the mapped classes."""
        return measurement.probabilities @ self._state_matrix(tuple(measurement.classes))

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        """Sector points and kernel targets for the emitted samples of ``measurement``."""
        n = len(measurement)
        if n == 0:
            return Observations.empty()
        if n == 1 and self._quiet_single_row(measurement):
            return _NOTHING
        positions = measurement.positions_m
        headings = measurement.headings_rad
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(headings))):
            raise ValueError(
                f"failure-zone kernel {self.id!r}: positions and headings must be finite"
            )
        probabilities = self.state_probabilities(measurement)
        states = np.argmax(probabilities, axis=1)
        emit = self._select_rows(positions, states)
        if not emit.any():
            return Observations.empty()
        depth = measurement.depth_m
        parts = []
        for row in np.flatnonzero(emit):
            reach, gamma, eta = self.parameters(float(depth[row]))
            if self.config.mixture == "one-hot":
                local, targets, weights = self._one_hot_sector(reach, gamma, eta, int(states[row]))
            else:
                local, targets, weights = self._soft_sector(reach, gamma, eta, probabilities[row])
            c, s = math.cos(headings[row]), math.sin(headings[row])
            points = local @ np.array([[c, s], [-s, c]]) + positions[row]
            parts.append(Observations(points, targets, weights))
        return parts[0] if len(parts) == 1 else Observations.concatenate(parts)

    def _quiet_single_row(self, measurement: LocatedMeasurement) -> bool:
        """True when a one-row measurement emits nothing; then the travel state is updated.

        The closed loop observes one sample per tick and most emit nothing: this answers
        those in plain floats, with the same decision as :meth:`_select_rows`. Rows that
        emit (or are invalid) return False untouched and take the general path.
        """
        previous = self._previous_position
        spacing = self.config.observation_spacing_m
        if previous is None or spacing <= 0:
            return False
        x, y = measurement.positions_m[0].tolist()
        heading = float(measurement.headings_rad[0])
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(heading)):
            return False
        row = measurement.probabilities[0].tolist()
        columns = self._state_columns(tuple(measurement.classes))
        totals = [0.0, 0.0, 0.0]
        for column, value in zip(columns, row, strict=True):
            totals[column] += value
        # The first maximum, as np.argmax picks it (the totals are finite).
        state, best = 0, totals[0]
        if totals[1] > best:
            state, best = 1, totals[1]
        if totals[2] > best:
            state = 2
        if state != self._previous_state:
            return False
        travel = self._travel_m + math.sqrt((x - previous[0]) ** 2 + (y - previous[1]) ** 2)
        if math.floor(travel / spacing) > math.floor(self._travel_m / spacing):
            return False
        self._travel_m = travel
        self._previous_position = (x, y)
        return True

    def _state_columns(self, classes: tuple[str, ...]) -> list[int]:
        """Kernel state index of each class column (cached per class tuple)."""
        columns = self._column_cache.get(classes)
        if columns is None:
            columns = [int(k) for k in np.argmax(self._state_matrix(classes), axis=1)]
            self._column_cache[classes] = columns
        return columns

    def _sector(self, outer_m: float, eta: float) -> FloatArray:
        """Polar grid of a sector reaching ``outer_m`` (the fingertip alone for 0)."""
        if outer_m <= 0:
            return np.zeros((1, 2))
        key = (outer_m, eta)
        local = self._sector_cache.get(key)
        if local is None:
            if len(self._sector_cache) > _CACHE_SIZE:
                self._sector_cache.clear()
            local = sector_offsets(outer_m, eta, self.config.sector_spacing_m)
            self._sector_cache[key] = local
        return local

    def _one_hot_sector(
        self, reach: float, gamma: float, eta: float, state: int
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Local points, targets and weights of one state's sector (cached)."""
        key = (reach, eta, state, self.pair_count == 0)
        cached = self._target_cache.get(key)
        if cached is not None:
            return cached
        if len(self._target_cache) > _CACHE_SIZE:
            self._target_cache.clear()
        c = self.config
        inner, outer = self.state_ranges(reach)
        half_angle = eta * c.jamming_angle_scale if state == 1 else eta
        theta = np.eye(3)[state]
        if state == 1 and c.jamming_shape == "disc":
            near_edge = c.jamming_disc_offset_scale * reach
            local = disc_offsets(
                near_edge + c.jamming_disc_radius_m, c.jamming_disc_radius_m, c.sector_spacing_m
            )
            distance = np.hypot(local[:, 0], local[:, 1])
            targets = kernel_targets(distance, gamma, 1)
            weights = np.ones(distance.size)
        else:
            local = self._sector(float(outer[state]), half_angle)
            distance = np.hypot(local[:, 0], local[:, 1])
            targets, weights = mixture_targets(
                distance, gamma * (c.free_gamma_scale if state == 0 else 1.0), theta, outer, inner
            )
        if state > 0:
            weights = weights * c.interaction_weight
            if self.pair_count == 0:
                weights = weights * c.first_pair_weight
        keep = weights > 0
        cached = (local[keep], targets[keep], weights[keep])
        self._target_cache[key] = cached
        return cached

    def _soft_sector(
        self, reach: float, gamma: float, eta: float, theta: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Local points, targets and weights of a soft mixture (not cached: θ varies).

        With the 'sector' jamming region the states share the sector and Eq. 3.4's mixture
        is renormalised where they overlap; the 'disc' lies apart from the free sector, so
        each state's region is emitted with its probability as weight.
        """
        if self.config.jamming_shape == "disc":
            states = [k for k in range(3) if theta[k] > 0]
            parts = [self._one_hot_sector(reach, gamma, eta, k) for k in states]
            local = np.concatenate([p[0] for p in parts])
            targets = np.concatenate([p[1] for p in parts])
            weights = np.concatenate([p[2] * theta[k] for p, k in zip(parts, states, strict=True)])
            keep = weights > 0
            return local[keep], targets[keep], weights[keep]
        inner, outer = self.state_ranges(reach)
        reaching = outer[theta > 0]
        local = self._sector(float(reaching.max()) if reaching.size else 0.0, eta)
        distance = np.hypot(local[:, 0], local[:, 1])
        targets, _ = mixture_targets(distance, gamma, theta, outer, inner)
        # Free movement counts once, jamming and contact with the interaction weight.
        scale = np.array([1.0, self.config.interaction_weight, self.config.interaction_weight])
        weights = state_coverage(distance, outer, inner).astype(np.float64) @ (theta * scale)
        keep = weights > 0
        return local[keep], targets[keep], weights[keep]

    def _select_rows(self, positions: FloatArray, states: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Which rows to emit; updates the travel state carried across calls.

        A plain-float loop: the closed loop sends one row at a time, where numpy's per-call
        overhead would dominate, and rows arriving together or one by one give the same
        floats.
        """
        spacing = self.config.observation_spacing_m
        emit = np.zeros(len(positions), dtype=bool)
        previous = self._previous_position
        travel = self._travel_m
        previous_state = self._previous_state
        for i, (x, y) in enumerate(positions.tolist()):
            state = int(states[i])
            if previous is None:
                emit[i] = True
            else:
                before = travel
                travel = before + math.sqrt((x - previous[0]) ** 2 + (y - previous[1]) ** 2)
                if spacing > 0:
                    emit[i] = math.floor(travel / spacing) > math.floor(before / spacing)
                else:
                    emit[i] = True
                if state != previous_state:
                    emit[i] = True
            previous = (x, y)
            previous_state = state
        self._travel_m = travel
        self._previous_position = previous
        self._previous_state = previous_state
        return emit

    # --- training from calibration recordings (issue 32 §2) -----------------------------------

    def fit(self, recordings: Sequence[CalibrationRecording]) -> None:
        """Fit the rupture distance, sector half-angle and depth schedule from calibration
        recordings (:func:`~hapticframe_failure_zone.fit_failure_zone` over all of them,
        movement indices kept apart per recording); the fitted fields replace the config's.

        Parameters
        ----------
        recordings : sequence of CalibrationRecording
            The classes map to kernel states through ``class_states``.

        Raises
        ------
        ValueError
            With no recordings, or when no movement became jammed.
        """
        if not recordings:
            raise ValueError("no calibration recordings given")
        parts: dict[str, list[np.ndarray]] = {k: [] for k in ("p", "h", "d", "m", "s")}
        outlines: list[FloatArray] = []
        base = 0
        for rec in recordings:
            state_of = np.array([STATES.index(self.config.class_states.get(c, "free"))
                                 for c in rec.classes], dtype=np.int64)
            parts["p"].append(rec.positions_m)
            parts["h"].append(rec.headings_rad)
            parts["d"].append(rec.depth_m)
            parts["s"].append(state_of[rec.labels()])
            parts["m"].append(rec.movement_index + base)
            base += int(rec.movement_index.max()) + 1 if len(rec) else 0
            outlines.extend(rec.outlines_m)
        p, h, d, m, s = (np.concatenate(parts[k]) for k in ("p", "h", "d", "m", "s"))
        fit = fit_failure_zone(p, h, d, m, s, outlines,
                               rake_angle_deg=self.config.rake_angle_deg)
        self._apply(fit.config_overrides())
        self._fit = fit

    def _apply(self, overrides: Mapping[str, Any]) -> None:
        self.config = _updated(self.config, overrides)
        if self.config.shear_band_angle_deg is not None:
            self.shear_band_angle_rad = math.radians(self.config.shear_band_angle_deg)
        self.rake_angle_rad = math.radians(self.config.rake_angle_deg)
        for cache in (self._class_cache, self._column_cache, self._sector_cache,
                      self._target_cache):
            cache.clear()
        self.reset()

    def training_report(self) -> Mapping[str, Any]:
        """The last fit's values (:meth:`FailureZoneFit.as_dict`); empty before a fit."""
        return {} if self._fit is None else self._fit.as_dict()

    def save(self, directory: str | Path) -> Path:
        """Write the last fit into ``directory/failure_zone_fit.json`` (plain JSON).

        Raises
        ------
        ValueError
            Before any fit.
        """
        if self._fit is None:
            raise ValueError("nothing to save: the failure-zone kernel has not been fitted")
        target = Path(directory) / self.ARTIFACT
        atomic_write(target, json.dumps(self._fit.as_dict(), indent=2) + "\n")
        return target

    def load(self, directory: str | Path) -> None:
        """Apply the fit :meth:`save` wrote into ``directory``."""
        self._apply(_read_fit(Path(directory))["config"])

    def describe(self) -> dict[str, Any]:
        """The current parameters, for progress lines and run metadata."""
        reach, gamma, eta = self.parameters()
        return {
            "schedule": self.config.schedule,
            "interacting_movements": self.interacting_movements,
            "pair_count": self.pair_count,
            "range_m": reach,
            "gamma_per_m2": gamma,
            "half_angle_rad": eta,
        }


def _read_fit(directory: Path) -> dict[str, Any]:
    """The saved fit in ``directory``, checked to carry the config fields it sets."""
    path = directory / FailureZoneKernel.ARTIFACT
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a failure-zone fit ({type(exc).__name__}: {exc})") from exc
    config = data.get("config") if isinstance(data, dict) else None
    allowed = set(FailureZoneConfig.model_fields) - {"model_dir"}
    if not isinstance(config, dict) or not set(config) <= allowed:
        raise ValueError(f"{path}: 'config' must map failure-zone config fields to values")
    return data


def _updated(config: FailureZoneConfig, overrides: Mapping[str, Any]) -> FailureZoneConfig:
    """``config`` with ``overrides`` applied, validated as a config (a bad value is a
    ``ValueError`` naming the field)."""
    return FailureZoneConfig.model_validate({**config.model_dump(), **dict(overrides)})
