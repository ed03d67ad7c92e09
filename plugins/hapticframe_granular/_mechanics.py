"""The failure zone ahead of a plate raked through dry granular material, as pure functions.

Wick and Perumpral's model (dissertation sections 3.3.1 and 3.4.3.1, Figure 3.2; the
material's parameters in section 3.5.1 and Table 3.1): a plate at depth ``d`` and angle ``α``
to the free surface fails a central wedge bounded by two side crescents. A shear band at
angle ``β`` leaves the plate's lower edge and meets the free surface at the *rupture
distance* ``r`` ahead of the plate; in the map plane the zone is the sector of radius ``r``
and half-angle ``η`` about the direction of motion (Eq. 3.2).

One policy for every function here:

- **Units.** SI: metres and radians, in and out. The published empirical constants are in
  degrees and centimetres; parameters that carry them end in ``_deg`` and are converted here.
- **Shapes.** Arguments broadcast against each other. When every argument is a scalar
  (Python or numpy) the result is a Python ``float``; when any is an ``ndarray`` or a
  sequence (empty and 0-d ones included) it is a float64 ``ndarray`` of the broadcast shape.
- **Domain.** An argument outside the stated domain (NaN and infinities included) raises a
  ``ValueError`` naming the argument and the first offending value (a count that is not a
  number at all, or a bool, raises ``TypeError``); nothing returns NaN.
  The only clipping is where the model itself stops meaning anything, and each function
  says where.
"""

from __future__ import annotations

import math
from typing import Any, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "SIDE_CRESCENT_ANGLE_CAP",
    "arthur_angle",
    "rupture_distance",
    "side_crescent_angle",
    "side_crescent_angle_analytic",
]

FloatArray = NDArray[np.float64]

#: Largest side-crescent half-angle η, rad (90°): the failure zone lies ahead of the plate.
SIDE_CRESCENT_ANGLE_CAP: float = math.pi / 2

_HALF_PI = math.pi / 2
_CM_PER_M = 100.0
# cot α below this is a vertical plate: cos(π/2) evaluates to 6e-17, not 0.
_VERTICAL_COT = 1e-12


@overload
def arthur_angle(friction_angle_rad: float, dilation_angle_rad: float) -> float: ...
@overload
def arthur_angle(friction_angle_rad: ArrayLike, dilation_angle_rad: ArrayLike) -> FloatArray: ...
def arthur_angle(
    friction_angle_rad: ArrayLike, dilation_angle_rad: ArrayLike
) -> float | FloatArray:
    """Shear-band angle β from the Arthur angle, β = π/4 − (φ + ψ)/4.

    Dissertation section 3.5.1 and Table 3.1, note † (Arthur et al., 1977): numerical
    simulations put the average shear-band angle close to the Arthur angle when φ > 20°.
    For the dissertation's sand mixture (φ = 42°, ψ = 12°) β = 31.5°.

    Parameters
    ----------
    friction_angle_rad : float or array_like
        Internal friction angle φ, rad, in (0, π/2).
    dilation_angle_rad : float or array_like
        Dilation angle ψ, rad, in [0, π/2).

    Returns
    -------
    float or ndarray
        β in rad, in (0, π/4) over that domain.

    Raises
    ------
    ValueError
        If φ or ψ is outside its domain or not finite.

    Examples
    --------
    >>> import math
    >>> round(math.degrees(arthur_angle(math.radians(42.0), math.radians(12.0))), 12)
    31.5
    """
    if _both_scalar(friction_angle_rad, dilation_angle_rad):
        phi, psi = float(friction_angle_rad), float(dilation_angle_rad)  # type: ignore[arg-type]
        _check_scalar("friction_angle_rad", phi, 0.0, _HALF_PI, low_open=True)
        _check_scalar("dilation_angle_rad", psi, 0.0, _HALF_PI, low_open=False)
        return math.pi / 4 - (phi + psi) / 4
    phi_a = np.asarray(friction_angle_rad, dtype=np.float64)
    psi_a = np.asarray(dilation_angle_rad, dtype=np.float64)
    _check_array("friction_angle_rad", phi_a, 0.0, _HALF_PI, low_open=True)
    _check_array("dilation_angle_rad", psi_a, 0.0, _HALF_PI, low_open=False)
    return np.asarray(math.pi / 4 - (phi_a + psi_a) / 4, dtype=np.float64)


@overload
def rupture_distance(
    depth_m: float, rake_angle_rad: float, shear_band_angle_rad: float
) -> float: ...
@overload
def rupture_distance(
    depth_m: ArrayLike, rake_angle_rad: ArrayLike, shear_band_angle_rad: ArrayLike
) -> FloatArray: ...
def rupture_distance(
    depth_m: ArrayLike, rake_angle_rad: ArrayLike, shear_band_angle_rad: ArrayLike
) -> float | FloatArray:
    """Distance ahead of the plate where the shear band meets the free surface, in metres.

    ``r = d (cot α + cot β)`` (Wick and Perumpral; dissertation Figure 3.2 and section
    3.4.3.1). For vertical raking (α = π/2) cot α is exactly 0, so ``r = d cot β``: 7.18,
    5.55, 4.73 and 4.32 cm at the depths 4.4, 3.4, 2.9 and 2.65 cm with β = 31.5°, which
    Table 3.1 lists truncated to millimetres (7.1, 5.5, 4.7, 4.3 cm).

    Parameters
    ----------
    depth_m : float or array_like
        Raking depth ``d`` of the plate's lower edge below the free surface, m, finite and
        non-negative (a caller with a measured depth above the surface clips it to 0 first).
    rake_angle_rad : float or array_like
        Plate angle α to the free surface, rad, in (0, π); π/2 is vertical raking.
    shear_band_angle_rad : float or array_like
        Shear-band angle β, rad, in (0, π/2) (see :func:`arthur_angle`).

    Returns
    -------
    float or ndarray
        ``r`` in metres, never negative. Where ``cot α + cot β < 0`` (a plate leaning
        forward past the shear band, α > π − β) the model has no wedge ahead of the plate
        and ``r`` is 0.

    Raises
    ------
    ValueError
        If an argument is outside its domain or not finite.
    """
    if _all_scalar(depth_m, rake_angle_rad, shear_band_angle_rad):
        d = float(depth_m)  # type: ignore[arg-type]
        alpha = float(rake_angle_rad)  # type: ignore[arg-type]
        beta = float(shear_band_angle_rad)  # type: ignore[arg-type]
        _check_scalar("depth_m", d, 0.0, math.inf, low_open=False)
        _check_scalar("rake_angle_rad", alpha, 0.0, math.pi, low_open=True)
        _check_scalar("shear_band_angle_rad", beta, 0.0, _HALF_PI, low_open=True)
        cot_alpha = math.cos(alpha) / math.sin(alpha)
        if abs(cot_alpha) < _VERTICAL_COT:
            cot_alpha = 0.0
        return max(d * (cot_alpha + 1.0 / math.tan(beta)), 0.0)
    d_a = np.asarray(depth_m, dtype=np.float64)
    alpha_a = np.asarray(rake_angle_rad, dtype=np.float64)
    beta_a = np.asarray(shear_band_angle_rad, dtype=np.float64)
    _check_array("depth_m", d_a, 0.0, math.inf, low_open=False)
    _check_array("rake_angle_rad", alpha_a, 0.0, math.pi, low_open=True)
    _check_array("shear_band_angle_rad", beta_a, 0.0, _HALF_PI, low_open=True)
    cot_alpha_a = np.cos(alpha_a) / np.sin(alpha_a)
    cot_alpha_a = np.where(np.abs(cot_alpha_a) < _VERTICAL_COT, 0.0, cot_alpha_a)
    return np.asarray(np.maximum(d_a * (cot_alpha_a + 1.0 / np.tan(beta_a)), 0.0))


@overload
def side_crescent_angle(
    pair_count: int, *, base_deg: float = ..., step_deg: float = ...
) -> float: ...
@overload
def side_crescent_angle(
    pair_count: ArrayLike, *, base_deg: float = ..., step_deg: float = ...
) -> FloatArray: ...
def side_crescent_angle(
    pair_count: ArrayLike, *, base_deg: float = 50.0, step_deg: float = 7.0
) -> float | FloatArray:
    """Table 3.1's empirical side-crescent half-angle η = (50 + 7n)°, in radians, capped at π/2.

    ``n`` is the number of *pairwise* interactions with the buried object so far (Table
    3.1, note ‡). The line passes 90° at n = 6; the result is capped at
    :data:`SIDE_CRESCENT_ANGLE_CAP` (π/2) because the failure zone of Figure 3.2 lies
    ahead of the plate (a sector wider than ±90° would reach behind it), and Wick and
    Perumpral's own formula, η = asin(...), cannot exceed π/2 either
    (:func:`side_crescent_angle_analytic`).

    Parameters
    ----------
    pair_count : int or array_like of int
        n, a non-negative integer (integral floats such as ``3.0`` are accepted).
    base_deg, step_deg : float
        The published constants 50° and 7° per pair, degrees; finite and non-negative.

    Returns
    -------
    float or ndarray
        η in rad, in [radians(base_deg), π/2] (π/2 when base_deg ≥ 90).

    Raises
    ------
    ValueError
        If ``pair_count`` is negative or not integral, or a constant is negative or not
        finite.
    TypeError
        If ``pair_count`` is a bool or not a number.
    """
    for name, value in (("base_deg", base_deg), ("step_deg", step_deg)):
        if not (math.isfinite(value) and value >= 0):
            raise ValueError(f"{name} must be finite and non-negative, got {value!r}")
    if np.ndim(pair_count) == 0 and not isinstance(pair_count, np.ndarray):
        n = _check_count(pair_count)
        try:
            degrees = base_deg + step_deg * n
        except OverflowError:  # an int beyond float range: past the cap unless step is 0
            degrees = base_deg if step_deg == 0 else math.inf
        return min(math.radians(degrees), SIDE_CRESCENT_ANGLE_CAP)
    counts = np.asarray(pair_count)
    if counts.dtype == np.bool_ or not (
        np.issubdtype(counts.dtype, np.integer) or np.issubdtype(counts.dtype, np.floating)
    ):
        raise TypeError(f"pair_count must hold non-negative integers, got dtype {counts.dtype}")
    n_a = counts.astype(np.float64)
    bad = ~(np.isfinite(n_a) & (n_a >= 0) & (n_a == np.floor(n_a)))
    if bad.any():
        value = n_a[bad].flat[0]
        raise ValueError(f"pair_count must hold non-negative integers, got {value!r}")
    eta = np.radians(base_deg + step_deg * n_a)
    return np.asarray(np.minimum(eta, SIDE_CRESCENT_ANGLE_CAP), dtype=np.float64)


def side_crescent_angle_analytic(range_m: float, rake_angle_rad: float) -> tuple[float, float]:
    """Wick and Perumpral's side-crescent angle η = asin((6.03 + 0.460 r + 0.0904 α) / r).

    The formula (dissertation Figure 3.2) is published with ``r`` in centimetres and ``α``
    in degrees; both are converted here. For the dissertation's own numbers the argument
    exceeds 1 (r = 7.1 cm, α = 90°: 17.4 / 7.1 ≈ 2.45), where arcsin is undefined: the
    argument is clipped to 1, so η is capped at π/2 as in :func:`side_crescent_angle`, and
    the unclipped argument is returned so that the caller can report the clipping.

    Parameters
    ----------
    range_m : float
        Rupture distance ``r``, m, finite and positive.
    rake_angle_rad : float
        Plate angle α to the free surface, rad, in (0, π).

    Returns
    -------
    eta_rad : float
        η in (0, π/2], never NaN.
    argument : float
        The unclipped argument of arcsin (finite, positive); above 1 it was clipped.

    Raises
    ------
    ValueError
        If an argument is outside its domain or not finite.
    """
    r = float(range_m)
    alpha = float(rake_angle_rad)
    _check_scalar("range_m", r, 0.0, math.inf, low_open=True)
    _check_scalar("rake_angle_rad", alpha, 0.0, math.pi, low_open=True)
    r_cm = r * _CM_PER_M
    argument = (6.03 + 0.460 * r_cm + 0.0904 * math.degrees(alpha)) / r_cm
    # Every term is positive, so the argument is too: only the upper clip can act.
    return math.asin(min(argument, 1.0)), argument


# --- validation -----------------------------------------------------------------------------


def _is_scalar(value: Any) -> bool:
    return not isinstance(value, np.ndarray) and np.ndim(value) == 0


def _both_scalar(a: Any, b: Any) -> bool:
    return _is_scalar(a) and _is_scalar(b)


def _all_scalar(*values: Any) -> bool:
    return all(_is_scalar(v) for v in values)


def _describe_interval(low: float, high: float, low_open: bool) -> str:
    # Every upper bound here is open.
    return f"{'(' if low_open else '['}{low:.6g}, {high:.6g})"


def _check_scalar(name: str, value: float, low: float, high: float, *, low_open: bool) -> None:
    above_low = value > low if low_open else value >= low
    if not (math.isfinite(value) and above_low and value < high):
        raise ValueError(
            f"{name} must be finite and lie in {_describe_interval(low, high, low_open)}, "
            f"got {value!r}"
        )


def _check_array(name: str, values: FloatArray, low: float, high: float, *, low_open: bool) -> None:
    above_low = values > low if low_open else values >= low
    bad = ~(np.isfinite(values) & above_low & (values < high))
    if bad.any():
        value = float(values[bad].flat[0])
        raise ValueError(
            f"{name} must be finite and lie in {_describe_interval(low, high, low_open)}, "
            f"got {value!r}"
        )


def _check_count(value: Any) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise TypeError(f"pair_count must be a non-negative integer, got {value!r}")
    integral = isinstance(value, (int, np.integer)) or (
        math.isfinite(value) and value == math.floor(value)
    )
    if not integral:
        raise ValueError(f"pair_count must be a non-negative integer, got {value!r}")
    n = int(value)
    if n < 0:
        raise ValueError(f"pair_count must be a non-negative integer, got {value!r}")
    return n
