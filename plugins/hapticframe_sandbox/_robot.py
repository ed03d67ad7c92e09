"""The simulated sandbox: a plate raked through sand towards buried objects.

The robot is also the world simulator. Each control step it advances the fingertip along a
straight exploratory movement, places the failure zone ahead of it (thesis Eq. 3.2, Figure
3.2), and computes the true interaction force: free plate drag modulated by the shear-band
nucleation cycle, a jamming surge once the failure zone reaches an object, and a stiff
contact force once the plate does. The sandbox force sensor reads that force from here.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import (
    BuildContext,
    ExploratoryMovement,
    MovementResult,
    Robot,
    RobotState,
    RunOutcome,
)

from . import _functional as F
from ._config import SandboxRobotConfig

__all__ = [
    "CONTACT",
    "FREE",
    "JAMMING",
    "STATE_NAMES",
    "GroundTruthLog",
    "MovementTruth",
    "SandboxRobot",
]

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


class SandboxRobot(Robot):
    """Simulated robot that rakes a rigid plate through a sandbox at constant depth and speed.

    Parameters
    ----------
    config : SandboxRobotConfig
    context : BuildContext
        Needs ``context.scene``; all randomness comes from ``context.rng``.
    """

    def __init__(self, config: SandboxRobotConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        if context.scene is None:
            raise ValueError(
                f"robot {context.id!r} (type 'sandbox') needs a scene: add a 'scene' section "
                "to the experiment"
            )
        self._scene = context.scene
        self._rng = context.rng
        self._dt = 1.0 / config.control_rate_hz
        self._beta_deg = (
            config.shear_band_angle_deg
            if config.shear_band_angle_deg is not None
            else context.scene.material.shear_band_angle_deg
        )
        if not 0.0 < self._beta_deg < 90.0:
            raise ValueError(
                f"robot {context.id!r}: shear-band angle {self._beta_deg}° from the scene "
                "material is outside (0, 90)"
            )
        # Bounding circles let far-away objects be skipped without sampling the sector.
        self._bounds = [
            (
                obj.centroid_m,
                float(np.max(np.linalg.norm(obj.outline(512) - obj.centroid_m, axis=1))),
            )
            for obj in self._scene.objects
        ]
        # Depth schedule (section 3.5.1): shrinks after each movement that reached an object.
        self._schedule_depth = config.depth_m
        self._next_reduction = config.depth_reduction_m
        self._interactions = 0
        # Clock and current movement.
        self._time = 0.0
        self._index = -1
        self._active = False
        self._closed = True
        self._halt_reason = ""
        home = context.scene.region.to_region().center_m
        self._state = RobotState(0.0, home, 0.0, config.depth_m, 0.0)
        # Ground-truth log, kept as growing lists and turned into arrays on demand.
        self._log_t: list[float] = []
        self._log_pos: list[NDArray[np.float64]] = []
        self._log_state: list[int] = []
        self._log_force: list[NDArray[np.float64]] = []
        self._log_index: list[int] = []
        self._log_depth: list[float] = []
        self._movements: list[MovementTruth] = []
        self._max_force = 0.0

    # --- Robot interface -----------------------------------------------------------------

    @property
    def control_rate_hz(self) -> float:
        return float(self.config.control_rate_hz)

    @property
    def state(self) -> RobotState:
        return self._state

    @property
    def halt_reason(self) -> str:
        return self._halt_reason

    def begin(self, movement: ExploratoryMovement) -> None:
        self._close_movement()
        cfg = self.config
        self._index += 1
        self._closed = False
        self._halt_reason = ""
        depth = self._schedule_depth if movement.depth_m is None else float(movement.depth_m)
        if not (math.isfinite(depth) and depth > 0):
            raise ValueError(f"robot {self.id!r}: movement depth must be positive, got {depth}")
        self._depth = depth
        self._speed = float(movement.speed_m_per_s)
        self._length = movement.length_m
        self._heading = movement.heading_rad
        self._direction = F.unit_vector(self._heading)
        self._start = movement.start_m
        self._travelled = 0.0
        self._rupture = F.rupture_distance_m(depth, cfg.rake_angle_deg, self._beta_deg)
        self._eta_deg = (
            cfg.side_crescent_angle_deg
            if cfg.side_crescent_angle_deg is not None
            else F.side_crescent_angle_deg(self._interactions // 2)
        )
        self._steady_drag = F.free_drag_n(depth, cfg.drag_coefficient_n_per_m2)
        # A fresh shear-band cycle at a random phase, and a stationary drag fluctuation.
        self._new_shear_cycle()
        self._cycle_position = self._rng.uniform(0.0, self._cycle_length)
        self._fluctuation = cfg.drag_fluctuation_fraction * self._rng.standard_normal()
        self._penetration = 0.0
        self._em_start_time = self._time
        self._em_max_state = FREE
        self._em_max_force = 0.0
        self._jam_onset = math.nan
        self._contact_onset = math.nan
        self._active = self._length > 0.0
        self._state = RobotState(self._time, self._start, self._heading, depth, 0.0)

    def step(self) -> RobotState | None:
        if not self._active:
            return None
        advance = min(self._speed * self._dt, self._length - self._travelled)
        self._travelled += advance
        # Time from the global step count: exact, and strictly increasing across movements.
        self._time = (len(self._log_t) + 1) * self._dt
        position = self._start + self._travelled * self._direction
        force, true_state = self._interaction(position, advance)
        self._record(position, force, true_state)
        self._state = RobotState(self._time, position, self._heading, self._depth, self._speed)
        if float(np.hypot(*force)) > self.config.force_limit_n:
            self.halt("force_limit")
        elif self._travelled >= self._length:
            self._active = False
        return self._state

    def halt(self, reason: str) -> None:
        """Stop the current movement; the first reason given for a movement is kept."""
        if self._active:
            self._active = False
            self._halt_reason = str(reason)

    def on_movement_end(self, result: MovementResult) -> None:
        self._close_movement()

    def finalize(self, outcome: RunOutcome) -> Mapping[str, Any]:
        self._close_movement()
        if outcome.figures:
            from ._plots import plot_movement_forces

            plot_movement_forces(
                self.ground_truth, self._movements, Path(outcome.out_dir) / "forces.png"
            )
        return {
            "max_force_n": float(self._max_force),
            "object_interactions": int(sum(m.interacted for m in self._movements)),
        }

    # --- ground truth --------------------------------------------------------------------

    @property
    def ground_truth(self) -> GroundTruthLog:
        """Every step so far: time, position, true state and force (a :class:`GroundTruthLog`)."""
        n = len(self._log_t)
        return GroundTruthLog(
            timestamps_s=np.asarray(self._log_t, dtype=np.float64),
            positions_m=np.asarray(self._log_pos, dtype=np.float64).reshape(n, 2),
            states=np.asarray(self._log_state, dtype=np.int64),
            forces_n=np.asarray(self._log_force, dtype=np.float64).reshape(n, 2),
            movement_index=np.asarray(self._log_index, dtype=np.int64),
            depth_m=np.asarray(self._log_depth, dtype=np.float64),
        )

    @property
    def steps_taken(self) -> int:
        """Number of steps logged so far (all movements)."""
        return len(self._log_t)

    def true_forces_since(self, first: int) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Timestamps ``(k,)`` and true forces ``(k, 2)`` of steps ``first, first+1, ...``."""
        t = np.asarray(self._log_t[first:], dtype=np.float64)
        f = np.asarray(self._log_force[first:], dtype=np.float64).reshape(t.size, 2)
        return t, f

    @property
    def movements(self) -> tuple[MovementTruth, ...]:
        """Truth of every finished movement (a movement finishes at the next begin or end call)."""
        return tuple(self._movements)

    @property
    def current_depth_m(self) -> float:
        """Depth the next movement will use unless it commands its own."""
        return float(self._schedule_depth)

    @property
    def shear_band_angle_deg(self) -> float:
        return float(self._beta_deg)

    # --- the world -----------------------------------------------------------------------

    def _new_shear_cycle(self) -> None:
        cfg = self.config
        jitter = cfg.shear_cycle_jitter
        self._cycle_length = (
            cfg.shear_cycle_length_fraction
            * self._rupture
            * self._rng.uniform(1 - jitter, 1 + jitter)
        )
        # Zero depth would make a zero-length cycle; keep the loop in step() finite.
        self._cycle_length = max(self._cycle_length, 1e-6)
        self._cycle_amplitude = cfg.shear_cycle_amplitude * self._rng.uniform(
            1 - jitter, 1 + jitter
        )

    def _interaction(
        self, position: NDArray[np.float64], advance: float
    ) -> tuple[NDArray[np.float64], int]:
        """True force vector and state after the plate moved ``advance`` to ``position``."""
        cfg = self.config
        # Shear-band nucleation: the drag builds over a cycle, then drops at a new band.
        self._cycle_position += advance
        while self._cycle_position >= self._cycle_length:
            self._cycle_position -= self._cycle_length
            self._new_shear_cycle()
        # Slow multiplicative fluctuation (an AR(1) process with the configured correlation time).
        decay = math.exp(-self._dt / cfg.drag_fluctuation_time_s)
        self._fluctuation = decay * self._fluctuation + math.sqrt(1 - decay * decay) * (
            cfg.drag_fluctuation_fraction * self._rng.standard_normal()
        )
        scale = max(0.0, 1.0 + self._fluctuation)
        drag = (
            self._steady_drag
            * F.startup_factor(self._travelled, self._rupture)
            * F.shear_cycle_factor(self._cycle_position / self._cycle_length, self._cycle_amplitude)
            * scale
        )
        force = -drag * self._direction
        hit_distance, hit_angle, in_contact = self._locate_objects(position)
        state = FREE
        if math.isfinite(hit_distance) and hit_distance <= self._rupture:
            state = JAMMING
            surge = F.jamming_force_n(
                hit_distance,
                self._rupture,
                cfg.jamming_gain_n_per_m,
                self._depth,
                cfg.jamming_exponent,
            )
            force = force - surge * scale * F.unit_vector(hit_angle)
        if in_contact:
            state = CONTACT
            self._penetration += advance
            force = (
                force
                - F.contact_force_n(self._penetration, cfg.contact_stiffness_n_per_m)
                * self._direction
            )
        else:
            self._penetration = 0.0
        return force, state

    def _locate_objects(self, position: NDArray[np.float64]) -> tuple[float, float, bool]:
        """Nearest object distance in the failure zone, its direction, and plate contact."""
        cfg = self.config
        reach = self._rupture + cfg.plate_width_m
        near = any(np.linalg.norm(position - c) <= radius + reach for c, radius in self._bounds)
        if not near:
            return math.inf, self._heading, False
        eta = math.radians(self._eta_deg)
        n_rays = cfg.sector_angular_samples
        offsets = np.zeros(1) if n_rays == 1 else np.linspace(-eta, eta, n_rays)
        angles = self._heading + offsets
        radii = np.linspace(0.0, self._rupture, cfg.sector_radial_samples)
        hits = F.first_hit_distances(position, angles, radii, self._scene.occupied)
        best = int(np.argmin(hits))
        edge = F.plate_edge_points(position, self._heading, cfg.plate_width_m)
        in_contact = bool(hits[best] == 0.0 or self._scene.occupied(edge).any())
        return float(hits[best]), float(angles[best]), in_contact

    def _record(
        self, position: NDArray[np.float64], force: NDArray[np.float64], state: int
    ) -> None:
        magnitude = float(np.hypot(force[0], force[1]))
        if state >= JAMMING and math.isnan(self._jam_onset):
            self._jam_onset = self._time
        if state == CONTACT and math.isnan(self._contact_onset):
            self._contact_onset = self._time
        self._em_max_state = max(self._em_max_state, state)
        self._em_max_force = max(self._em_max_force, magnitude)
        self._max_force = max(self._max_force, magnitude)
        self._log_t.append(self._time)
        self._log_pos.append(position)
        self._log_state.append(state)
        self._log_force.append(force)
        self._log_index.append(self._index)
        self._log_depth.append(self._depth)

    def _close_movement(self) -> None:
        """Book the current movement once: its truth record and the depth schedule."""
        if self._closed:
            return
        self._closed = True
        self._active = False
        truth = MovementTruth(
            index=self._index,
            depth_m=self._depth,
            rupture_distance_m=self._rupture,
            side_crescent_angle_deg=self._eta_deg,
            start_time_s=self._em_start_time,
            end_time_s=self._time,
            jamming_onset_s=self._jam_onset,
            contact_onset_s=self._contact_onset,
            max_state=self._em_max_state,
            max_force_n=self._em_max_force,
            halt_reason=self._halt_reason,
        )
        self._movements.append(truth)
        if truth.interacted:
            # Soil displaced around the object: rake shallower next time (1, 0.5, 0.25 cm ...).
            self._interactions += 1
            self._schedule_depth = max(
                self.config.min_depth_m, self._schedule_depth - self._next_reduction
            )
            self._next_reduction *= self.config.depth_reduction_ratio
