"""The analytic sandbox world: failure-zone mechanics (thesis §3.3, Eq. 3.2, Figure 3.2).

Each step the plate's force is the free drag modulated by the shear-band nucleation cycle
and a slow fluctuation, a jamming surge once the failure zone ahead of the plate reaches an
object, and a stiff contact force once the plate does. Its parameters are the ``sandbox``
robot's config fields.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from hapticframe import Scene
from hapticframe.kinds import PlateMovement, PlateSample, World, WorldResponse
from hapticframe_granular import arthur_angle, rupture_distance, side_crescent_angle

from . import _functional as F
from ._config import SandboxRobotConfig
from ._truth import CONTACT, FREE, JAMMING

__all__ = ["AnalyticSandWorld"]


class AnalyticSandWorld(World):
    """The sandbox's own world: the failure-zone model of the dissertation.

    Parameters
    ----------
    config : SandboxRobotConfig
        The drag, shear-band, jamming, contact and failure-zone sampling fields are used.
    scene : Scene
        The buried objects and the sand's material.
    rng : numpy.random.Generator
        Source of the shear-band jitter and the drag fluctuation.
    """

    def __init__(self, config: SandboxRobotConfig, scene: Scene, rng: np.random.Generator) -> None:
        self.config = config
        self.scene = scene
        self._rng = rng
        material = scene.material
        self.shear_band_angle_rad = (
            math.radians(config.shear_band_angle_deg)
            if config.shear_band_angle_deg is not None
            else arthur_angle(
                math.radians(material.friction_angle_deg),
                math.radians(material.dilation_angle_deg),
            )
        )
        self._rake_rad = math.radians(config.rake_angle_deg)
        # Bounding circles let far-away objects be skipped without sampling the sector:
        # (centre x, centre y, radius) in plain floats for the per-step test.
        self._bounds = [
            (
                *np.asarray(obj.centroid_m, dtype=np.float64).tolist(),
                float(np.max(np.linalg.norm(obj.outline(512) - obj.centroid_m, axis=1))),
            )
            for obj in scene.objects
        ]

    def side_angle_rad(self, interactions: int) -> float:
        """The failure zone's half-angle to the side after ``interactions`` movements that
        reached an object (the configured one, else thesis Eq. 3.3 per pair of them)."""
        cfg = self.config
        return (
            math.radians(cfg.side_crescent_angle_deg)
            if cfg.side_crescent_angle_deg is not None
            else side_crescent_angle(interactions // 2)
        )

    def begin(self, movement: PlateMovement) -> None:
        cfg = self.config
        self._movement = movement
        self._heading = movement.heading_rad
        self._direction_xy = movement.direction
        self._depth = movement.depth_m
        self._decay = math.exp(-movement.control_period_s / cfg.drag_fluctuation_time_s)
        self._innovation = math.sqrt(1 - self._decay * self._decay)
        self._sector_geometry: tuple[NDArray[np.float64], ...] | None = None
        # How far ahead of the plate the failure zone reaches (Eq. 3.2).
        self._rupture = rupture_distance(
            movement.depth_m, self._rake_rad, self.shear_band_angle_rad
        )
        # An object matters once the fingertip is within its bounding radius plus the
        # failure zone's reach and the plate: (x, y, that distance squared) per object.
        reach = self._rupture + movement.plate_width_m
        self._near_limits = [
            (cx, cy, (radius + reach) ** 2, radius) for cx, cy, radius in self._bounds
        ]
        self._eta_rad = self.side_angle_rad(movement.interactions)
        self._steady_drag = F.free_drag_n(movement.depth_m, cfg.drag_coefficient_n_per_m2)
        # A fresh shear-band cycle at a random phase, and a stationary drag fluctuation.
        self._new_shear_cycle()
        self._cycle_position = self._rng.uniform(0.0, self._cycle_length)
        self._fluctuation = cfg.drag_fluctuation_fraction * self._rng.standard_normal()
        self._penetration = 0.0

    def _new_shear_cycle(self) -> None:
        cfg = self.config
        jitter = cfg.shear_cycle_jitter
        self._cycle_length = (
            cfg.shear_cycle_length_fraction
            * self._rupture
            * self._rng.uniform(1 - jitter, 1 + jitter)
        )
        # Zero depth would make a zero-length cycle; keep the loop in respond() finite.
        self._cycle_length = max(self._cycle_length, 1e-6)
        self._cycle_amplitude = cfg.shear_cycle_amplitude * self._rng.uniform(
            1 - jitter, 1 + jitter
        )

    def respond(self, plate: PlateSample) -> WorldResponse:
        cfg = self.config
        advance = plate.advance_m
        # Shear-band nucleation: the drag builds over a cycle, then drops at a new band.
        self._cycle_position += advance
        while self._cycle_position >= self._cycle_length:
            self._cycle_position -= self._cycle_length
            self._new_shear_cycle()
        # Slow multiplicative fluctuation (an AR(1) process with the configured correlation time).
        self._fluctuation = self._decay * self._fluctuation + self._innovation * (
            cfg.drag_fluctuation_fraction * self._rng.standard_normal()
        )
        scale = max(0.0, 1.0 + self._fluctuation)
        drag = (
            self._steady_drag
            * F.startup_factor(plate.travelled_m, self._rupture)
            * F.shear_cycle_factor(self._cycle_position / self._cycle_length, self._cycle_amplitude)
            * scale
        )
        dx, dy = self._direction_xy
        fx, fy = -drag * dx, -drag * dy
        hit_distance, hit_angle, in_contact = self._locate_objects(plate.position_m)
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
            push = surge * scale
            ux, uy = F.unit_vector(hit_angle).tolist()
            fx, fy = fx - push * ux, fy - push * uy
        if in_contact:
            state = CONTACT
            self._penetration += advance
            spring = F.contact_force_n(self._penetration, cfg.contact_stiffness_n_per_m)
            fx, fy = fx - spring * dx, fy - spring * dy
        else:
            self._penetration = 0.0
        return WorldResponse((float(fx), float(fy)), state)

    def _locate_objects(self, xy: tuple[float, float]) -> tuple[float, float, bool]:
        """Nearest object distance in the failure zone, its direction, and plate contact."""
        x, y = xy
        dx, dy = self._direction_xy
        # An object matters when its bounding circle is within reach and not wholly behind
        # the plate: the sector's rays fan out at most 90 degrees from the heading (the side
        # angle is capped there) and the plate lies across it, so nothing sampled is behind.
        # Rounding in these tests cannot change the answer: an object just outside the
        # bound lies a plate half-width beyond anything the sector or plate samples.
        for cx, cy, limit_squared, radius in self._near_limits:
            if (x - cx) ** 2 + (y - cy) ** 2 <= limit_squared and (
                (cx - x) * dx + (cy - y) * dy >= -radius
            ):
                break
        else:
            return math.inf, self._heading, False
        position = np.array(xy)
        geometry = self._sector_geometry
        if geometry is None:
            geometry = self._sector_geometry = self._fan_geometry()
        angles, radii, directions, ray_offsets, edge_offsets = geometry
        hits = F.first_hit_distances(
            position, angles, radii, self.scene.occupied,
            directions=directions, ray_offsets=ray_offsets,
        )
        best = int(np.argmin(hits))
        in_contact = bool(
            hits[best] == 0.0 or self.scene.occupied(position + edge_offsets).any()
        )
        return float(hits[best]), float(angles[best]), in_contact

    def _fan_geometry(self) -> tuple[NDArray[np.float64], ...]:
        """The current movement's sector rays and plate face relative to the fingertip.

        Fixed for a movement (heading, rupture distance and side angle change only between
        movements), so they are computed at the first step near an object and reused:
        ray angles, radii, ray directions, ``radii x directions`` and the plate-edge
        offsets, each exactly as :func:`F.first_hit_distances` and
        :func:`F.plate_edge_points` would compute them.
        """
        cfg = self.config
        eta = self._eta_rad
        n_rays = cfg.sector_angular_samples
        offsets = np.zeros(1) if n_rays == 1 else np.linspace(-eta, eta, n_rays)
        angles = self._heading + offsets
        radii = np.linspace(0.0, self._rupture, cfg.sector_radial_samples)
        directions = F.unit_vector(angles)
        ray_offsets = radii[None, :, None] * directions[:, None, :]
        edge_offsets = F.plate_edge_offsets(self._heading, self._movement.plate_width_m)
        return angles, radii, directions, ray_offsets, edge_offsets
