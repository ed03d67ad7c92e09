"""Plate-drag geometry and force pieces of the simulated sandbox, as pure array functions.

The failure zone ahead of a plate raked through dry granular material (Wick and Perumpral;
Kobayakawa et al.; thesis section 3.3.1 and Figure 3.2) is a central wedge bounded by two
side crescents. In the map plane it is modelled as the circular sector of radius ``r`` (the
rupture distance) and half-angle ``eta`` (the side-crescent angle) centred on the direction
of motion (Eq. 3.2). The rupture distance, the side-crescent angle and the shear-band
(Arthur) angle come from :mod:`hapticframe_granular`, shared with the failure-zone sensor
model; the geometry and force pieces below are the simulator's own. Everything here is
stateless; the robot class strings it together.

Units: metres, seconds, newtons, radians, except parameters whose names end in ``_deg``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "contact_force_n",
    "first_hit_distances",
    "free_drag_n",
    "jamming_force_n",
    "plate_edge_offsets",
    "plate_edge_points",
    "sector_ray_points",
    "shear_cycle_factor",
    "TrapezoidTiming",
    "startup_factor",
    "trapezoid_motion",
    "trapezoid_timing",
    "unit_vector",
]

FloatArray = NDArray[np.float64]


def unit_vector(angle_rad: ArrayLike) -> FloatArray:
    """``(..., 2)`` unit vectors at ``angle_rad`` counter-clockwise from +x."""
    a = np.asarray(angle_rad, dtype=np.float64)
    return np.stack([np.cos(a), np.sin(a)], axis=-1)


def sector_ray_points(
    position_m: ArrayLike,
    heading_rad: float,
    radius_m: float,
    half_angle_rad: float,
    n_radial: int,
    n_angular: int,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Sample the failure-zone sector on rays fanning out from the fingertip.

    Parameters
    ----------
    position_m : (2,)
        Fingertip position (the sector's apex).
    heading_rad : float
        Direction of motion (the sector's axis).
    radius_m : float
        Sector radius (the rupture distance).
    half_angle_rad : float
        Sector half-angle η.
    n_radial, n_angular : int
        Samples per ray (including the apex) and number of rays (≥ 1; one ray is the axis).

    Returns
    -------
    points : (n_angular, n_radial, 2)
        Sample points, ray by ray, from the apex outwards.
    radii : (n_radial,)
        Distance of each sample from the apex.
    ray_angles : (n_angular,)
        Absolute direction of each ray.
    """
    if n_radial < 2 or n_angular < 1:
        raise ValueError("need n_radial >= 2 and n_angular >= 1")
    radii = np.linspace(0.0, float(radius_m), n_radial)
    if n_angular == 1:
        offsets = np.zeros(1)
    else:
        offsets = np.linspace(-half_angle_rad, half_angle_rad, n_angular)
    ray_angles = heading_rad + offsets
    directions = unit_vector(ray_angles)  # (n_angular, 2)
    points = (
        np.asarray(position_m, dtype=np.float64) + radii[None, :, None] * directions[:, None, :]
    )
    return points, radii, ray_angles


def first_hit_distances(
    position_m: ArrayLike,
    ray_angles_rad: FloatArray,
    radii_m: FloatArray,
    occupied: Callable[[FloatArray], NDArray[np.bool_]],
    refine_iterations: int = 12,
    *,
    directions: FloatArray | None = None,
    ray_offsets: FloatArray | None = None,
) -> FloatArray:
    """Distance along each ray to the first occupied point, ``inf`` where a ray hits nothing.

    The rays are sampled at ``radii_m`` (ascending, starting at 0); the first occupied sample
    brackets the boundary, which bisection then refines. Refinement keeps the distance a
    continuous function of the fingertip position, so the simulated force has no staircase.

    Parameters
    ----------
    position_m : (2,)
    ray_angles_rad : (m,)
    radii_m : (k,)
        Ascending sample distances along each ray; ``radii_m[0]`` should be 0.
    occupied : callable
        Maps ``(p, 2)`` points to a ``(p,)`` bool mask (``Scene.occupied``).
    refine_iterations : int
        Bisection steps; the error is the radial spacing divided by ``2**refine_iterations``.
    directions, ray_offsets : array, optional
        ``unit_vector(ray_angles_rad)`` (m, 2) and ``radii_m[None, :, None] *
        directions[:, None, :]`` (m, k, 2), when the caller keeps them between calls
        with the same rays (a robot within one movement); computed here otherwise.
    """
    origin = np.asarray(position_m, dtype=np.float64)
    if directions is None:
        directions = unit_vector(ray_angles_rad)
    m, k = directions.shape[0], radii_m.size
    if ray_offsets is None:
        ray_offsets = radii_m[None, :, None] * directions[:, None, :]
    pts = origin + ray_offsets
    mask = np.asarray(occupied(pts.reshape(-1, 2)), dtype=bool).reshape(m, k)
    hit = mask.any(axis=1)
    out = np.full(m, np.inf)
    if not hit.any():
        return out
    first = np.argmax(mask, axis=1)
    rays = np.flatnonzero(hit)
    at_apex = first[rays] == 0
    out[rays[at_apex]] = 0.0
    rays = rays[~at_apex]
    if rays.size == 0:
        return out
    lo = radii_m[first[rays] - 1].copy()  # free
    hi = radii_m[first[rays]].copy()  # occupied
    dirs = directions[rays]
    for _ in range(refine_iterations):
        mid = 0.5 * (lo + hi)
        inside = np.asarray(occupied(origin + mid[:, None] * dirs), dtype=bool)
        hi = np.where(inside, mid, hi)
        lo = np.where(inside, lo, mid)
    out[rays] = hi
    return out


def plate_edge_points(
    position_m: ArrayLike, heading_rad: float, plate_width_m: float, n: int = 9
) -> FloatArray:
    """``(n, 2)`` points across the plate face, perpendicular to the direction of motion."""
    return np.asarray(position_m, dtype=np.float64) + plate_edge_offsets(
        heading_rad, plate_width_m, n
    )


def plate_edge_offsets(heading_rad: float, plate_width_m: float, n: int = 9) -> FloatArray:
    """``(n, 2)`` offsets of :func:`plate_edge_points` from the fingertip."""
    normal = unit_vector(heading_rad + np.pi / 2)
    offsets = np.linspace(-plate_width_m / 2, plate_width_m / 2, n)
    return offsets[:, None] * normal


def free_drag_n(depth_m: ArrayLike, drag_coefficient_n_per_m2: float) -> FloatArray | float:
    """Steady plate-drag force for free movement, ``F = c d²``.

    Passive-earth-pressure theory gives a drag proportional to ``γ w d²`` for a plate of
    width ``w`` in material of unit weight ``γ``; the coefficient ``c`` lumps those together
    and is calibrated so that ``d = 4.4 cm`` gives the 10–20 N of Figure 3.6.
    """
    d = np.asarray(depth_m, dtype=np.float64)
    f = drag_coefficient_n_per_m2 * d * d
    return float(f) if f.ndim == 0 else f


def startup_factor(travelled_m: ArrayLike, rupture_distance: float) -> FloatArray | float:
    """Fraction of the steady drag reached after the plate has moved ``travelled_m``.

    The failure zone needs about one rupture distance of travel to develop from rest; a
    linear build-up over that distance keeps the start-up force rate at its lowest.
    """
    if type(travelled_m) is float:  # a robot step: the same clip in plain floats
        if rupture_distance <= 0:
            return 1.0
        return min(max(travelled_m / rupture_distance, 0.0), 1.0)
    s = np.asarray(travelled_m, dtype=np.float64)
    if rupture_distance <= 0:
        out = np.ones_like(s)
    else:
        out = np.clip(s / rupture_distance, 0.0, 1.0)
    return float(out) if out.ndim == 0 else out


def shear_cycle_factor(phase: ArrayLike, amplitude: ArrayLike) -> FloatArray | float:
    """Sawtooth multiplier of the drag over one shear-band nucleation cycle.

    Within a cycle (``phase`` in [0, 1)) the drag builds linearly from ``1 − A/2`` to
    ``1 + A/2`` as the shear band steepens, then drops when a new band nucleates.
    """
    if type(phase) is float and type(amplitude) is float:  # a robot step, in plain floats
        return 1.0 + amplitude * (min(max(phase, 0.0), 1.0) - 0.5)
    p = np.asarray(phase, dtype=np.float64)
    a = np.asarray(amplitude, dtype=np.float64)
    out = 1.0 + a * (np.clip(p, 0.0, 1.0) - 0.5)
    return float(out) if out.ndim == 0 else out


def jamming_force_n(
    hit_distance_m: ArrayLike,
    rupture_distance: float,
    gain_n_per_m: float,
    depth_m: float,
    exponent: float,
) -> FloatArray | float:
    """Extra force once the failure zone reaches an object (granular jamming).

    The force chains of the failure zone press on the object and back on the plate. The
    surge is ``g d ((r − s)/r)^p`` for an object at distance ``s ≤ r`` ahead: zero as the zone
    first touches it, growing as the plate approaches, ``g d`` when the plate reaches it.
    It scales with depth ``d`` because the jammed wedge does; with ``p > 1`` the force rate
    grows too as the plate approaches.
    """
    s = np.asarray(hit_distance_m, dtype=np.float64)
    if rupture_distance <= 0:
        engaged = np.where(s <= 0, 1.0, 0.0)
    else:
        engaged = np.clip((rupture_distance - s) / rupture_distance, 0.0, 1.0)
        engaged = np.where(np.isfinite(s), engaged, 0.0)
    out = gain_n_per_m * depth_m * engaged**exponent
    return float(out) if out.ndim == 0 else out


def contact_force_n(penetration_m: ArrayLike, stiffness_n_per_m: float) -> FloatArray | float:
    """Force of direct contact: a stiff spring on the distance pushed into the object."""
    p = np.clip(np.asarray(penetration_m, dtype=np.float64), 0.0, None)
    out = stiffness_n_per_m * p
    return float(out) if out.ndim == 0 else out


# --- speed profile ------------------------------------------------------------------------------


class TrapezoidTiming(NamedTuple):
    """Timing of a trapezoidal speed profile over one straight movement (seconds, m/s)."""

    peak_speed_m_per_s: float
    ramp_end_s: float
    cruise_end_s: float
    total_s: float


def trapezoid_timing(
    length_m: float, speed_m_per_s: float, acceleration_m_per_s2: float
) -> TrapezoidTiming:
    """Accelerate at ``acceleration_m_per_s2`` to ``speed_m_per_s``, cruise, decelerate to
    stop after ``length_m``.

    A movement shorter than ``speed² / acceleration`` never reaches the speed: its profile is
    a triangle peaking at ``sqrt(acceleration x length)`` halfway (no cruise).
    """
    if not (length_m >= 0 and speed_m_per_s > 0 and acceleration_m_per_s2 > 0):
        raise ValueError("need length_m >= 0, speed_m_per_s > 0 and acceleration_m_per_s2 > 0")
    a = float(acceleration_m_per_s2)
    peak = min(float(speed_m_per_s), math.sqrt(a * length_m))
    ramp = peak / a
    # Cruise covers what the two ramps (each peak² / 2a) leave of the length; none in a
    # triangle (where rounding could otherwise leave a sliver).
    cruise = (length_m - peak * peak / a) / peak if peak == speed_m_per_s else 0.0
    cruise = max(cruise, 0.0)
    return TrapezoidTiming(peak, ramp, ramp + cruise, 2 * ramp + cruise)


def trapezoid_motion(
    elapsed_s: float, length_m: float, acceleration_m_per_s2: float, timing: TrapezoidTiming
) -> tuple[float, float]:
    """Distance travelled and speed ``elapsed_s`` after the start of a trapezoidal profile.

    Plain floats in and out (the robot calls it once per control step). Before the start:
    ``(0, 0)``; from ``timing.total_s`` on: ``(length_m, 0)``.
    """
    a = acceleration_m_per_s2
    peak, ramp_end, cruise_end, total = timing
    if elapsed_s <= 0.0:
        return 0.0, 0.0
    if elapsed_s >= total:
        return length_m, 0.0
    if elapsed_s < ramp_end:
        return 0.5 * a * elapsed_s * elapsed_s, a * elapsed_s
    if elapsed_s < cruise_end:
        return 0.5 * peak * ramp_end + peak * (elapsed_s - ramp_end), peak
    # Decelerating: mirror the ramp from the end, so the profile ends exactly at length_m.
    remaining = total - elapsed_s
    return length_m - 0.5 * a * remaining * remaining, a * remaining
