"""The failure-zone kernel sensor model: located class probabilities become map observations.

For each emitted sample the sector ahead of the fingertip (range r, half-angle η about the
direction of motion, Eq. 3.2) is sampled on a polar grid and every point gets the occupancy
target of the three-state kernel mixture (Eqs. 3.3-3.4). The parameters follow one of two
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
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import (
    BuildContext,
    LocatedMeasurement,
    MovementResult,
    Observations,
    SensorModel,
)

from ._config import FailureZoneConfig
from ._functional import (
    STATES,
    FailureZoneAngleWarning,
    analytic_side_angle,
    arthur_angle_deg,
    depth_schedule,
    empirical_gamma,
    empirical_side_angle,
    mixture_targets,
    range_from_gamma,
    rupture_distance,
    rupture_gamma,
    sector_offsets,
)

__all__ = ["FailureZoneKernel"]

FloatArray = NDArray[np.float64]

#: Shear-band angle when neither the config nor a scene gives one (φ = 42°, ψ = 12°).
_DEFAULT_SHEAR_BAND_DEG = arthur_angle_deg(42.0, 12.0)


class FailureZoneKernel(SensorModel):
    """Kernel-based sensor model of the granular failure zone (dissertation section 3.4.3.1).

    Parameters
    ----------
    config : FailureZoneConfig
    context : BuildContext
        ``context.scene.material`` supplies the shear-band angle when the config does not.
    """

    def __init__(self, config: FailureZoneConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        if config.shear_band_angle_deg is not None:
            beta_deg = config.shear_band_angle_deg
        elif context.scene is not None:
            beta_deg = context.scene.material.shear_band_angle_deg
        else:
            beta_deg = _DEFAULT_SHEAR_BAND_DEG
        if not 0.0 < beta_deg < 90.0:
            raise ValueError(f"shear-band angle must lie in (0, 90) degrees, got {beta_deg}")
        self.shear_band_angle_rad = math.radians(beta_deg)
        self.rake_angle_rad = math.radians(config.rake_angle_deg)
        self._warned_angle = False
        self.reset()

    # --- state between movements ------------------------------------------------------------

    def reset(self) -> None:
        """Forget the interaction count and the travel bookkeeping."""
        self.interacting_movements = 0
        self._start_movement()

    def _start_movement(self) -> None:
        self._previous_position: FloatArray | None = None
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
            Measured fingertip depth; used by the analytic schedule when finite (negative
            depths count as 0). NaN or infinity falls back to the depth schedule.
        """
        c = self.config
        if c.schedule == "empirical":
            gamma = empirical_gamma(
                self.pair_count, c.empirical_gamma_scale_cm2, c.empirical_gamma_ratio
            )
            reach = float(range_from_gamma(gamma))
            eta = empirical_side_angle(
                self.pair_count, c.empirical_eta_base_deg, c.empirical_eta_step_deg
            )
            return float(np.clip(reach, c.min_range_m, c.max_range_m)), gamma, eta
        if c.use_measured_depth and math.isfinite(depth_m):
            depth = max(depth_m, 0.0)
        else:
            depth = self.scheduled_depth_m()
        reach = float(rupture_distance(depth, self.rake_angle_rad, self.shear_band_angle_rad))
        reach = float(np.clip(reach, c.min_range_m, c.max_range_m))
        eta, argument = analytic_side_angle(reach, self.rake_angle_rad)
        if abs(argument) > 1.0 and not self._warned_angle:
            self._warned_angle = True
            warnings.warn(
                f"failure-zone kernel {self.id!r}: the side-crescent formula gives "
                f"asin({argument:.3g}) at r = {reach * 100:.2f} cm; clipped to "
                f"eta = {math.degrees(eta):.1f} deg",
                FailureZoneAngleWarning,
                stacklevel=2,
            )
        return reach, float(rupture_gamma(reach)), max(eta, 0.0)

    # --- observations ---------------------------------------------------------------------------

    def state_probabilities(self, measurement: LocatedMeasurement) -> FloatArray:
        """(n, 3) probabilities of (free, jamming, contact), summed over the mapped classes."""
        unknown = [name for name in measurement.classes if name not in self.config.class_states]
        if unknown:
            raise ValueError(
                f"failure-zone kernel {self.id!r}: classes {unknown} have no kernel state; "
                f"class_states maps {sorted(self.config.class_states)}"
            )
        to_state = np.zeros((len(measurement.classes), 3))
        for column, name in enumerate(measurement.classes):
            to_state[column, STATES.index(self.config.class_states[name])] = 1.0
        return measurement.probabilities @ to_state

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        """Sector points and kernel targets for the emitted samples of ``measurement``."""
        n = len(measurement)
        if n == 0:
            return Observations.empty()
        positions = measurement.positions_m
        headings = measurement.headings_rad
        if not (np.all(np.isfinite(positions)) and np.all(np.isfinite(headings))):
            raise ValueError(
                f"failure-zone kernel {self.id!r}: positions and headings must be finite"
            )
        probabilities = self.state_probabilities(measurement)
        states = np.argmax(probabilities, axis=1)
        if self.config.mixture == "one-hot":
            theta = np.eye(3)[states]
        else:
            theta = probabilities
        emit = self._select_rows(positions, states)
        depth = measurement.depth_m
        parts = []
        sector_cache: dict[tuple[float, float], FloatArray] = {}
        for row in np.flatnonzero(emit):
            reach, gamma, eta = self.parameters(float(depth[row]))
            if theta[row, 0] + theta[row, 1] > 0:
                key = (reach, eta)
                if key not in sector_cache:
                    sector_cache[key] = sector_offsets(reach, eta, self.config.sector_spacing_m)
                local = sector_cache[key]
            else:  # contact only: range 0, the fingertip alone
                local = np.zeros((1, 2))
            targets, weights = mixture_targets(
                np.hypot(local[:, 0], local[:, 1]), gamma, theta[row], (reach, reach, 0.0)
            )
            c, s = math.cos(headings[row]), math.sin(headings[row])
            points = local @ np.array([[c, s], [-s, c]]) + positions[row]
            keep = weights > 0
            parts.append(Observations(points[keep], targets[keep], weights[keep]))
        return Observations.concatenate(parts)

    def _select_rows(self, positions: FloatArray, states: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Which rows to emit; updates the travel state carried across calls."""
        first_of_movement = self._previous_position is None
        anchor = positions[0] if first_of_movement else self._previous_position
        steps = np.diff(np.vstack([anchor, positions]), axis=0)
        # Sequential cumulative sum seeded with the carried value: bit-identical whether the
        # rows arrive together or one by one.
        travel = np.cumsum(np.concatenate([[self._travel_m], np.hypot(steps[:, 0], steps[:, 1])]))
        spacing = self.config.observation_spacing_m
        if spacing > 0:
            marks = np.floor(travel / spacing)
            emit = marks[1:] > marks[:-1]
        else:
            emit = np.ones(len(positions), dtype=bool)
        previous_states = np.concatenate([[self._previous_state], states[:-1]])
        emit |= states != previous_states
        if first_of_movement:
            emit[0] = True
        self._travel_m = float(travel[-1])
        self._previous_position = positions[-1].copy()
        self._previous_state = int(states[-1])
        return emit

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
