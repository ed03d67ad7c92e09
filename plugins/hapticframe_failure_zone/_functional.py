"""Pure array functions of the failure-zone sensor model (dissertation section 3.4.3.1).

Everything here is stateless numpy: the kernel bandwidth γ_r (Eq. 3.3 and Table 3.1's
empirical line), the depth schedule, the three-state kernel targets of Eqs. 3.3-3.4 and the
sampling of the sector of Eq. 3.2. The granular mechanics that size the sector (the Arthur
angle, the rupture distance, the side-crescent angle) live in :mod:`hapticframe_granular`,
shared with the ``sandbox`` simulator.

Units are SI (metres, radians, m^-2) unless a name says otherwise; the published empirical
formula for γ_r is stated in cm^-2 and is converted explicitly.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "STATES",
    "FailureZoneAngleWarning",
    "depth_schedule",
    "disc_offsets",
    "empirical_gamma",
    "kernel_targets",
    "mixture_targets",
    "range_from_gamma",
    "rupture_gamma",
    "sector_offsets",
    "state_coverage",
]

FloatArray = NDArray[np.float64]

#: The three environmental interaction states of Eq. 3.4, in kernel order k = 0, 1, 2.
STATES: tuple[str, str, str] = ("free", "jamming", "contact")

_LN2 = math.log(2.0)
_CM_PER_M = 100.0


class FailureZoneAngleWarning(UserWarning):
    """The analytic side-crescent formula left the domain of arcsin and was clipped.

    See :func:`hapticframe_granular.side_crescent_angle_analytic`.
    """


def rupture_gamma(range_m: ArrayLike) -> FloatArray:
    """Kernel bandwidth γ_r = ln 2 / r² (m⁻²) so that the kernel halves at the range ``r``."""
    r = np.asarray(range_m, dtype=np.float64)
    if np.any(~np.isfinite(r)) or np.any(r <= 0):
        raise ValueError("range_m must be finite and positive")
    return _LN2 / r**2


def range_from_gamma(gamma_per_m2: ArrayLike) -> FloatArray:
    """The range where ``exp(-γ r²) = 1/2``: ``r = sqrt(ln 2 / γ)`` (inverse of rupture_gamma)."""
    g = np.asarray(gamma_per_m2, dtype=np.float64)
    if np.any(~np.isfinite(g)) or np.any(g <= 0):
        raise ValueError("gamma must be finite and positive")
    return np.sqrt(_LN2 / g)


def empirical_gamma(
    pair_count: int, scale_cm2: float = 72.0, ratio: float = 0.82
) -> float:
    """Table 3.1's bandwidth γ_r = 1 / (72 · 0.82ⁿ) cm⁻², returned in m⁻².

    Parameters
    ----------
    pair_count : int
        n, the number of pairwise interactions with the buried object so far.
    scale_cm2, ratio : float
        The published constants 72 cm² and 0.82.
    """
    n = _check_count(pair_count)
    if not (scale_cm2 > 0 and ratio > 0):
        raise ValueError("scale_cm2 and ratio must be positive")
    gamma_per_cm2 = 1.0 / (scale_cm2 * ratio**n)
    return gamma_per_cm2 * _CM_PER_M**2


def depth_schedule(
    interacting_movements: int,
    initial_depth_m: float = 0.044,
    first_decrement_m: float = 0.01,
    decrement_ratio: float = 0.5,
    min_depth_m: float = 0.001,
) -> float:
    """Raking depth after ``k`` interacting movements: 4.4 cm, then −1, −0.5, −0.25 cm...

    ``d_k = d_0 − δ (1 − ρᵏ) / (1 − ρ)`` (a geometric series of decrements; ``k δ`` when
    ``ρ = 1``), never below ``min_depth_m``.
    """
    k = _check_count(interacting_movements)
    if decrement_ratio == 1.0:
        removed = first_decrement_m * k
    else:
        removed = first_decrement_m * (1.0 - decrement_ratio**k) / (1.0 - decrement_ratio)
    return max(initial_depth_m - removed, min_depth_m)


def kernel_targets(distance_m: ArrayLike, gamma_per_m2: float, state: int) -> FloatArray:
    """Occupancy targets of one state's kernel, Eq. 3.3: ``a_k − exp(−γ ||x − x_t||²)``.

    ``a_k = (2 + k) / 2``: free movement rises from 0 at the fingertip to 1/2 at the
    rupture distance, jamming from 1/2 to 1, contact is 1 at the fingertip. Targets are
    clipped to [0, 1] (beyond the range the jamming and contact kernels would exceed 1).
    """
    if state not in (0, 1, 2):
        raise ValueError(f"state must be 0, 1 or 2, got {state}")
    if not (math.isfinite(gamma_per_m2) and gamma_per_m2 >= 0):
        raise ValueError("gamma must be finite and non-negative")
    d = np.asarray(distance_m, dtype=np.float64)
    a_k = 0.5 * (2 + state)
    return np.clip(a_k - np.exp(-gamma_per_m2 * d**2), 0.0, 1.0)


def mixture_targets(
    distance_m: ArrayLike,
    gamma_per_m2: float,
    theta: ArrayLike,
    ranges_m: ArrayLike,
    inner_ranges_m: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """The three-state mixture of Eq. 3.4 at points ``distance_m`` from the fingertip.

    Each state ``k`` speaks only about points within its own radial interval
    ``[inner_k, r_k]`` (contact has range 0; Eq. 3.4 has every inner bound 0). A point
    covered by the set ``K(x)`` of states gets the θ-weighted mean of their kernels,
    renormalised over ``K(x)``, and a weight equal to the mass ``Σ_{k∈K(x)} θ_k``: with
    one-hot θ this is exactly Eq. 3.4 (weight 1 where the active state reaches, nothing
    elsewhere); with soft θ a point beyond the contact point is not pulled towards "free"
    merely because contact claims part of the probability.

    Parameters
    ----------
    distance_m : (m,) array
        Distances ``||x − x_t||`` of the sector points.
    gamma_per_m2 : float
        Bandwidth γ_r shared by the free and jamming kernels.
    theta : (3,) array
        State probabilities (free, jamming, contact), non-negative.
    ranges_m : (3,) array
        Outer range of each state.
    inner_ranges_m : (3,) array, optional
        Inner range of each state (default 0: the whole disc sector up to the range).

    Returns
    -------
    targets : (m,) float64 in [0, 1]
    weights : (m,) float64 in [0, 1]
        Zero where no state with positive θ reaches the point.
    """
    d = np.asarray(distance_m, dtype=np.float64).reshape(-1)
    th = np.asarray(theta, dtype=np.float64).reshape(-1)
    rk = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
    lo = np.zeros(3) if inner_ranges_m is None else np.asarray(inner_ranges_m, float).reshape(-1)
    if th.shape != (3,) or rk.shape != (3,) or lo.shape != (3,):
        raise ValueError("theta and the ranges must have three entries (free, jamming, contact)")
    if not (np.all(np.isfinite(th)) and np.all(th >= 0)):
        raise ValueError("theta must be finite and non-negative")
    covered = state_coverage(d, rk, lo)
    mass = covered.astype(np.float64) @ th
    weighted = np.zeros_like(d)
    for k in range(3):
        if th[k] > 0:
            weighted += np.where(covered[:, k], th[k] * kernel_targets(d, gamma_per_m2, k), 0.0)
    targets = np.divide(weighted, mass, out=np.zeros_like(d), where=mass > 0)
    return np.clip(targets, 0.0, 1.0), mass


def state_coverage(
    distance_m: ArrayLike, ranges_m: ArrayLike, inner_ranges_m: ArrayLike
) -> NDArray[np.bool_]:
    """``(m, 3)`` True where a point lies within a state's radial interval ``[inner, range]``.

    A relative tolerance of 1e-12 keeps the sector's innermost and outermost rings covered.
    """
    d = np.asarray(distance_m, dtype=np.float64).reshape(-1, 1)
    outer = np.asarray(ranges_m, dtype=np.float64).reshape(1, -1)
    inner = np.asarray(inner_ranges_m, dtype=np.float64).reshape(1, -1)
    return (d <= outer * (1 + 1e-12) + 1e-12) & (d >= inner * (1 - 1e-12) - 1e-12)


def sector_offsets(range_m: float, half_angle_rad: float, spacing_m: float) -> FloatArray:
    """Points of the sector of Eq. 3.2 in the fingertip frame (+x = direction of motion).

    A polar grid: rings every ≤ ``spacing_m`` from the fingertip out to exactly ``range_m``,
    each ring sampled every ≤ ``spacing_m`` of arc between ``−η`` and ``+η`` (both edges
    included). The fingertip itself is the first point. A range of 0 gives only it.

    Returns
    -------
    (m, 2) float64
    """
    if not (math.isfinite(range_m) and range_m >= 0):
        raise ValueError(f"range_m must be finite and non-negative, got {range_m}")
    if not (math.isfinite(half_angle_rad) and 0 <= half_angle_rad <= math.pi):
        raise ValueError(f"half angle must lie in [0, pi], got {half_angle_rad}")
    if not (math.isfinite(spacing_m) and spacing_m > 0):
        raise ValueError(f"spacing_m must be finite and positive, got {spacing_m}")
    parts = [np.zeros((1, 2))]
    if range_m > 0:
        n_rings = max(1, math.ceil(range_m / spacing_m))
        full_circle = half_angle_rad >= math.pi
        for rho in np.linspace(0.0, range_m, n_rings + 1)[1:]:
            n_arcs = max(1, math.ceil(2.0 * half_angle_rad * rho / spacing_m))
            if half_angle_rad == 0:  # a ray straight ahead
                phi = np.zeros(1)
            elif full_circle:  # -π and +π are one point
                phi = np.linspace(-math.pi, math.pi, n_arcs, endpoint=False)
            else:
                phi = np.linspace(-half_angle_rad, half_angle_rad, n_arcs + 1)
            parts.append(rho * np.column_stack([np.cos(phi), np.sin(phi)]))
    return np.concatenate(parts)


def disc_offsets(centre_ahead_m: float, radius_m: float, spacing_m: float) -> FloatArray:
    """Points of a disc centred ``centre_ahead_m`` straight ahead of the fingertip.

    A polar grid about the disc's centre: its centre, then rings every ≤ ``spacing_m`` out
    to exactly ``radius_m``, each sampled every ≤ ``spacing_m`` of arc (+x = direction of
    motion, the fingertip at the origin).

    Returns
    -------
    (m, 2) float64
    """
    for name, value in (("centre_ahead_m", centre_ahead_m), ("radius_m", radius_m)):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and non-negative, got {value}")
    if not (math.isfinite(spacing_m) and spacing_m > 0):
        raise ValueError(f"spacing_m must be finite and positive, got {spacing_m}")
    parts = [np.zeros((1, 2))]
    if radius_m > 0:
        n_rings = max(1, math.ceil(radius_m / spacing_m))
        for rho in np.linspace(0.0, radius_m, n_rings + 1)[1:]:
            n_arcs = max(3, math.ceil(2.0 * math.pi * rho / spacing_m))
            phi = np.linspace(-math.pi, math.pi, n_arcs, endpoint=False)
            parts.append(rho * np.column_stack([np.cos(phi), np.sin(phi)]))
    return np.concatenate(parts) + np.array([centre_ahead_m, 0.0])


def _check_count(value: int) -> int:
    n = int(value)
    if n != value or n < 0:
        raise ValueError(f"a count must be a non-negative integer, got {value!r}")
    return n
