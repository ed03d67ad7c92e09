"""The force observer of thesis Eq. 3.10 as pure functions: fit and apply.

The wrist force/torque sensor reads the environment's force plus the inertial and
gravitational load of the end effector beyond it, plus a constant offset:

    f_sens = m_e R a_IMU + f_env + ε                                    (Eq. 3.10)

``a_IMU`` is the IMU's specific force (its raw accelerometer: kinematic acceleration minus
gravity, in the IMU frame), ``R`` the rotation from the IMU frame to the force sensor's
frame (their misalignment), ``m_e`` the mass beyond the sensor and ``ε`` the sensor's
offset. In free motion in air ``f_env = 0``, so ``(m_e, R, ε)`` follow by least squares
from a recording of forces and accelerations:

    min  Σ_i || f_i − m R a_i − ε ||²   over  m ∈ ℝ,  R ∈ SO(3),  ε ∈ ℝ³.

For fixed ``(m, R)`` the best ``ε`` is ``f̄ − m R ā``, which leaves the centred problem
``min Σ ||f̃_i − m R ã_i||²``. Since ``||R ã|| = ||ã||`` it equals
``S_f − 2 m tr(R H) + m² S_a`` with ``H = Σ ã_i f̃_iᵀ``: the best ``m`` is
``tr(R H) / S_a`` and the best ``R`` maximises ``|tr(R H)|``. With ``H = U S Vᵀ`` the
maximum of ``tr(R H)`` over SO(3) is ``R = V diag(1, 1, d) Uᵀ`` with
``d = det(V Uᵀ)`` (orthogonal Procrustes, Kabsch's determinant correction); a negative
gain is the same problem for ``−H``. Both are solved and the smaller residual is kept.

Excitation
----------
Only the *variation* of the accelerations carries information (a constant part is
indistinguishable from ``ε``). When the centred accelerations span a single direction
``u`` (motions along one axis, small tilts about one axis), the data fix ``R u`` but not
the rotation about ``u``: every rotation that maps ``u`` onto the observed force direction
fits equally well, and an unconstrained Procrustes solution would pick one of them by the
noise. :func:`fit_force_observer` then warns (:class:`ExcitationWarning`) and returns the
*smallest* such rotation, the one whose rotation about ``u`` is zero: the part of ``R`` the
data cannot see is kept at the identity. With no varying direction at all, ``m_e = 0`` and
``R = I``, and ``ε`` absorbs the constant load.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from hapticframe.geometry import wxyz_from_rotation_matrix

__all__ = [
    "MIN_EXCITATION_M_PER_S2",
    "MIN_RELATIVE_EXCITATION",
    "ExcitationWarning",
    "ObserverFit",
    "apply_force_observer",
    "fit_force_observer",
    "rotation_angle_rad",
]

FloatArray = NDArray[np.float64]

#: A direction counts as excited when the accelerations' standard deviation along it is at
#: least this (m/s²) ...
MIN_EXCITATION_M_PER_S2 = 0.05
#: ... and at least this fraction of the largest standard deviation.
MIN_RELATIVE_EXCITATION = 0.05
#: Tolerance (relative to the fit's score) under which the two signs of the gain tie.
_TIE = 1e-12


class ExcitationWarning(UserWarning):
    """The recording does not excite enough acceleration directions to identify ``R``."""


def rotation_angle_rad(rotation: ArrayLike) -> float:
    """Angle of a rotation matrix (its distance from the identity), in ``[0, π]``."""
    m = np.asarray(rotation, dtype=np.float64)
    return float(np.arccos(np.clip((np.trace(m) - 1.0) / 2.0, -1.0, 1.0)))


def check_rotation(rotation: ArrayLike, what: str = "rotation", tol: float = 1e-6) -> FloatArray:
    """``rotation`` as a float64 ``(3, 3)`` array; ValueError unless it lies in SO(3)."""
    m = np.asarray(rotation, dtype=np.float64)
    if m.shape != (3, 3) or not np.all(np.isfinite(m)):
        raise ValueError(f"{what} must be a finite 3×3 matrix, got shape {m.shape}")
    if not np.allclose(m @ m.T, np.eye(3), atol=tol) or abs(np.linalg.det(m) - 1.0) > tol:
        raise ValueError(f"{what} is not a rotation (orthogonal with determinant +1)")
    return m


@dataclass(frozen=True)
class ObserverFit:
    """Parameters of Eq. 3.10 and, after :func:`fit_force_observer`, how well they fit.

    Parameters
    ----------
    mass_kg : float
        ``m_e``, the gain from specific force (m/s²) to force (N); negative when the sensor's
        axes point opposite to the IMU's.
    rotation : (3, 3) float64
        ``R``, sensor ← IMU.
    bias_n : (3,) float64
        ``ε``, the sensor's constant offset in the sensor frame.
    samples : int
        Rows the fit used (0 for parameters given directly).
    rows_dropped : int
        Rows left out because a force or acceleration component was not finite.
    raw_rms_n : float or None
        RMS norm of the forces as read (what the observer removes in free motion).
    residual_rms_n : float or None
        RMS norm of ``f − m_e R a − ε`` over the fit's rows.
    excitation_std_m_per_s2 : (3,) float64 or None
        Standard deviation of the accelerations along their principal directions, largest
        first.
    excitation_axes : (3, 3) float64 or None
        Those directions (rows, unit vectors in the IMU frame).
    excited_directions : int
        How many of them count as excited (see :data:`MIN_EXCITATION_M_PER_S2`).
    rotation_std_deg : (3,) float64 or None
        Approximate standard error of ``R``'s rotation about each principal direction
        (infinite about a direction the data cannot see).
    warning : str or None
        The :class:`ExcitationWarning` message the fit issued, if any.
    """

    mass_kg: float
    rotation: FloatArray
    bias_n: FloatArray
    samples: int = 0
    rows_dropped: int = 0
    raw_rms_n: float | None = None
    residual_rms_n: float | None = None
    excitation_std_m_per_s2: FloatArray | None = field(default=None, repr=False)
    excitation_axes: FloatArray | None = field(default=None, repr=False)
    excited_directions: int = 3
    rotation_std_deg: FloatArray | None = field(default=None, repr=False)
    warning: str | None = None

    def __post_init__(self) -> None:
        mass = float(self.mass_kg)
        if not np.isfinite(mass):
            raise ValueError(f"mass_kg must be finite, got {self.mass_kg}")
        bias = np.asarray(self.bias_n, dtype=np.float64)
        if bias.shape != (3,) or not np.all(np.isfinite(bias)):
            raise ValueError(f"bias_n must be 3 finite numbers, got {bias.tolist()}")
        object.__setattr__(self, "mass_kg", mass)
        object.__setattr__(self, "rotation", check_rotation(self.rotation).copy())
        object.__setattr__(self, "bias_n", bias.copy())

    @classmethod
    def identity(cls) -> ObserverFit:
        """No mass, no misalignment, no offset: the observer passes the force through."""
        return cls(0.0, np.eye(3), np.zeros(3))

    @property
    def rotation_wxyz(self) -> FloatArray:
        """``R`` as a unit quaternion ``(w, x, y, z)``."""
        return wxyz_from_rotation_matrix(self.rotation)

    @property
    def condition(self) -> float | None:
        """Largest over second-largest excitation standard deviation (inf when the second
        is zero); None for parameters given directly."""
        std = self.excitation_std_m_per_s2
        if std is None:
            return None
        return float(std[0] / std[1]) if std[1] > 0 else float("inf")

    def report(self) -> dict[str, Any]:
        """Plain JSON values (no NaN or infinity: those become None)."""

        condition = self.condition
        return {
            "mass_kg": self.mass_kg,
            "rotation": self.rotation.tolist(),
            "rotation_wxyz": self.rotation_wxyz.tolist(),
            "rotation_angle_deg": float(np.degrees(rotation_angle_rad(self.rotation))),
            "bias_n": self.bias_n.tolist(),
            "samples": self.samples,
            "rows_dropped": self.rows_dropped,
            "raw_rms_n": self.raw_rms_n,
            "residual_rms_n": self.residual_rms_n,
            "excitation_std_m_per_s2": _plain(self.excitation_std_m_per_s2),
            "excitation_axes": _plain(self.excitation_axes),
            "excited_directions": self.excited_directions,
            "condition": condition if condition is not None and np.isfinite(condition) else None,
            "rotation_std_deg": _plain(self.rotation_std_deg),
            "warning": self.warning,
        }


def _plain(value: FloatArray | None) -> Any:
    """Nested lists of floats with None for NaN and infinity (strict JSON has neither)."""
    if value is None:
        return None
    array = np.asarray(value, dtype=np.float64)
    cleaned = array.astype(object)
    cleaned[~np.isfinite(array)] = None
    listed: Any = cleaned.tolist()
    return listed


def _finite_rows(*arrays: FloatArray) -> NDArray[np.bool_]:
    ok = np.ones(arrays[0].shape[0], dtype=bool)
    for array in arrays:
        ok &= np.all(np.isfinite(array), axis=1)
    return ok


def _as_rows(values: ArrayLike, name: str) -> FloatArray:
    array = np.asarray(values, dtype=np.float64)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"{name} must have shape (n, 3), got {array.shape}")
    return array


def _procrustes(h: FloatArray) -> FloatArray:
    """The rotation maximising ``tr(R h)`` (Kabsch: the determinant fixed to +1)."""
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    return np.asarray(vt.T @ np.diag([1.0, 1.0, d]) @ u.T, dtype=np.float64)


def _smallest_rotation(u: FloatArray, w: FloatArray) -> FloatArray:
    """The rotation of least angle mapping unit vector ``u`` onto unit vector ``w``.

    Its axis is ``u × w``, so it does not turn about ``u`` beyond what that takes.
    Antiparallel vectors give a half turn about an axis perpendicular to ``u``.
    """
    axis = np.cross(u, w)
    s = float(np.linalg.norm(axis))
    c = float(np.dot(u, w))
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        # Half turn about the axis perpendicular to u nearest to a coordinate axis.
        helper = np.eye(3)[int(np.argmin(np.abs(u)))]
        k = np.cross(u, helper)
        k /= np.linalg.norm(k)
        return np.asarray(2.0 * np.outer(k, k) - np.eye(3), dtype=np.float64)
    k = axis / s
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + s * kx + (1.0 - c) * (kx @ kx), dtype=np.float64)


def _format_vector(v: FloatArray) -> str:
    rounded = np.round(v, 2) + 0.0  # + 0.0 turns -0.0 into 0.0
    return "(" + ", ".join(f"{x:+.2f}" for x in rounded) + ")"


def fit_force_observer(
    forces_n: ArrayLike,
    accelerations: ArrayLike,
    *,
    min_excitation_m_per_s2: float = MIN_EXCITATION_M_PER_S2,
    min_relative_excitation: float = MIN_RELATIVE_EXCITATION,
) -> ObserverFit:
    """Least-squares ``m_e``, ``R ∈ SO(3)`` and ``ε`` of Eq. 3.10 from free motions in air.

    Parameters
    ----------
    forces_n : (n, 3) array_like
        Force sensor readings (sensor frame), ideally low-pass filtered.
    accelerations : (n, 3) array_like
        IMU specific force (raw accelerometer, gravity included) in m/s², aligned with the
        forces and filtered the same way.
    min_excitation_m_per_s2, min_relative_excitation : float
        When a principal direction of the accelerations counts as excited (absolute standard
        deviation, and fraction of the largest one).

    Returns
    -------
    ObserverFit

    Raises
    ------
    ValueError
        On mismatched shapes, or fewer than 3 rows where every component is finite.

    Warns
    -----
    ExcitationWarning
        When fewer than two acceleration directions are excited: the rotation about the
        single excited direction (or all of ``R`` and ``m_e``, when none is) cannot be
        identified and is kept at the identity (see the module docstring).

    Notes
    -----
    Rows with a non-finite force or acceleration component are left out (counted in
    ``rows_dropped``). Both signs of the gain are solved and the smaller residual kept;
    when they tie (a single excited direction), the positive gain (a mass) is kept.
    """
    f_all = _as_rows(forces_n, "forces_n")
    a_all = _as_rows(accelerations, "accelerations")
    if f_all.shape != a_all.shape:
        raise ValueError(f"forces {f_all.shape} and accelerations {a_all.shape} differ in length")
    ok = _finite_rows(f_all, a_all)
    f, a = f_all[ok], a_all[ok]
    n = f.shape[0]
    if n < 3:
        raise ValueError(f"the fit needs at least 3 rows with finite values, got {n}")
    f_mean, a_mean = f.mean(axis=0), a.mean(axis=0)
    fc, ac = f - f_mean, a - a_mean
    s_a = float(np.sum(ac * ac))
    h = ac.T @ fc

    # Excitation: principal directions of the centred accelerations.
    eigvals, eigvecs = np.linalg.eigh(ac.T @ ac / n)
    order = np.argsort(eigvals)[::-1]
    std = np.sqrt(np.clip(eigvals[order], 0.0, None))
    axes = eigvecs[:, order].T
    # A direction's sign is arbitrary: make its largest component positive, for the message.
    axes *= np.sign(axes[np.arange(3), np.argmax(np.abs(axes), axis=1)])[:, None]
    floor = max(min_excitation_m_per_s2, min_relative_excitation * float(std[0]))
    excited = int(np.sum(std >= floor))

    message: str | None = None
    if excited >= 2:
        candidates = []
        for sign in (1.0, -1.0):
            rotation = _procrustes(sign * h)
            score = float(np.trace(rotation @ h))
            candidates.append((-(score * score) / s_a, rotation, score))
        (loss_pos, r_pos, score_pos), (loss_neg, r_neg, score_neg) = candidates
        scale = max(abs(loss_pos), abs(loss_neg), 1e-300)
        if loss_neg < loss_pos - _TIE * scale:
            rotation, mass = r_neg, score_neg / s_a
        else:
            rotation, mass = r_pos, score_pos / s_a
    elif excited == 1:
        u = axes[0]
        alpha = ac @ u
        b = fc.T @ alpha / float(alpha @ alpha)  # = m R u, the force per unit of excitation
        gain = float(np.linalg.norm(b))
        if gain == 0.0:
            rotation, mass = np.eye(3), 0.0
        else:
            # m R u = b and m (−R) u = −b fit equally: the data cannot tell the sign, so the
            # physical one (a mass is positive) is taken.
            rotation, mass = _smallest_rotation(u, b / gain), gain
        others = " and ".join(_format_vector(v) for v in axes[1:])
        message = (
            f"the accelerations vary along one direction only, {_format_vector(u)} in the IMU "
            f"frame (standard deviation {std[0]:.3g} m/s²; along {others} only "
            f"{std[1]:.3g} and {std[2]:.3g} m/s², below {floor:.3g}): the rotation R about "
            "that direction is not identifiable from this recording. R is the smallest "
            "rotation that maps it onto its force direction (no rotation about it). Record "
            "free motions that tilt the tool about at least two axes"
        )
    else:
        rotation, mass = np.eye(3), 0.0
        message = (
            f"the accelerations do not vary (standard deviations {std[0]:.3g}, {std[1]:.3g}, "
            f"{std[2]:.3g} m/s², below {floor:.3g}) along any direction: neither m_e nor R is "
            "identifiable; kept m_e = 0 and R = identity, and ε absorbs the constant load. "
            "Record free motions that tilt the tool about at least two axes"
        )
    if message is not None:
        warnings.warn(message, ExcitationWarning, stacklevel=2)

    bias = f_mean - mass * (rotation @ a_mean)
    residual = f - mass * (a @ rotation.T) - bias
    residual_rms = float(np.sqrt(np.mean(np.sum(residual * residual, axis=1))))
    # Standard error of a small rotation δθ about each principal direction k: the
    # information is n m² (σ_j² + σ_l²) / σ_f² over the other two directions j, l, with σ_f²
    # the residual variance per force component (Gauss–Newton on f = m R (a + δθ × a)).
    sigma_f = residual_rms / np.sqrt(3.0)
    lever = np.array([std[1] ** 2 + std[2] ** 2, std[0] ** 2 + std[2] ** 2,
                      std[0] ** 2 + std[1] ** 2])
    info = n * mass * mass * lever
    with np.errstate(divide="ignore"):
        rotation_std = np.where(info > 0, sigma_f / np.sqrt(np.where(info > 0, info, 1.0)), np.inf)
    if excited < 2:
        rotation_std[0] = np.inf  # fixed by the identity choice, not by the data
    return ObserverFit(
        mass_kg=mass,
        rotation=rotation,
        bias_n=bias,
        samples=n,
        rows_dropped=int(f_all.shape[0] - n),
        raw_rms_n=float(np.sqrt(np.mean(np.sum(f * f, axis=1)))),
        residual_rms_n=residual_rms,
        excitation_std_m_per_s2=std,
        excitation_axes=axes,
        excited_directions=excited,
        rotation_std_deg=np.degrees(rotation_std),
        warning=message,
    )


def apply_force_observer(
    forces: ArrayLike, accelerations: ArrayLike, fit: ObserverFit
) -> FloatArray:
    """Environment force ``f_env = f_sens − m_e R a_IMU − ε`` (Eq. 3.10), sensor frame.

    Parameters
    ----------
    forces : (n, 3) array_like
    accelerations : (n, 3) array_like
    fit : ObserverFit

    Returns
    -------
    (n, 3) float64
        NaN in exactly the rows where a force or acceleration component is not finite:
        those rows are invalid, never a silently wrong number.
    """
    f = _as_rows(forces, "forces")
    a = _as_rows(accelerations, "accelerations")
    if f.shape != a.shape:
        raise ValueError(f"forces {f.shape} and accelerations {a.shape} differ in length")
    ok = _finite_rows(f, a)
    out = np.full(f.shape, np.nan)
    out[ok] = f[ok] - fit.mass_kg * (a[ok] @ fit.rotation.T) - fit.bias_n
    return out
