"""Kinematics of a Barrett WAM (pure numpy): joint angles ↔ fingertip position, motor counts.

Frames: standard Denavit-Hartenberg (``T_i = Rz(θ_i) Tz(d_i) Tx(a_i) Rx(α_i)``, as libbarrett's
``kinematics.moving`` rows), the arm's base placed in the map frame (z up, the free surface at
z = 0, depth = −z) by a translation and a yaw, and the fingertip a fixed point in the last
joint's frame.

Published numbers (:data:`WAM4`, :data:`WAM7`), read from Barrett's libbarrett configuration
(``config/wam4.conf``, ``config/wam7w.conf``): the DH rows, the joint-to-motor matrices
``j2mp`` (motor radians = ``j2mp @ joint radians``; joints 2 and 3, and 5 and 6 on a 7-DOF
arm, are cable differentials) and the standard home postures. Joint ranges are Barrett's
published WAM ranges (J1 ±2.6, J2 ±2.0, J3 ±2.8, J4 −0.9...3.1 rad; the 7-DOF wrist's from a
public WAM URDF). None of these has been checked against an arm here.

Inverse kinematics is position-only damped least squares (DLS) from a seed, with two secondary
objectives in the Jacobian's null space: the tool axis pointing down (a 4-DOF arm cannot hold
an orientation and a position at once: this is a preference, not a constraint) and the joints
away from their limits. Straight lines are solved point by point, each from the last.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["WAM4", "WAM7", "ArmPreset", "DHLink", "IKResult", "SerialArm", "Transmission"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class DHLink:
    """One standard DH row: ``Rz(θ + theta_offset_rad) Tz(d_m) Tx(a_m) Rx(alpha_rad)``."""

    a_m: float
    alpha_rad: float
    d_m: float
    theta_offset_rad: float = 0.0


@dataclass(frozen=True)
class ArmPreset:
    """A WAM's published kinematic model."""

    name: str
    links: tuple[DHLink, ...]
    j2mp: tuple[tuple[float, ...], ...]
    limits_rad: tuple[tuple[float, float], ...]
    home_rad: tuple[float, ...]
    tool_offset_m: tuple[float, float, float]
    tool_axis: tuple[float, float, float]
    ik_seed_rad: tuple[float, ...]


_HALF_PI = 0.5 * math.pi
_ARM4 = (
    DHLink(0.0, -_HALF_PI, 0.0),  # base yaw
    DHLink(0.0, _HALF_PI, 0.0),  # shoulder pitch
    DHLink(0.045, -_HALF_PI, 0.55),  # shoulder twist (upper arm, 0.55 m)
    DHLink(-0.045, _HALF_PI, 0.0),  # elbow
)
_J2MP4 = (
    (-42.0, 0.0, 0.0, 0.0),
    (0.0, 28.25, -16.8155, 0.0),
    (0.0, -28.25, -16.8155, 0.0),
    (0.0, 0.0, 0.0, -18.0),
)

#: The 4-DOF WAM (libbarrett ``wam4.conf``); the fingertip 0.36 m out along the forearm (the
#: toolplate) plus a 0.15 m raking finger.
WAM4 = ArmPreset(
    name="wam4",
    links=_ARM4,
    j2mp=_J2MP4,
    limits_rad=((-2.6, 2.6), (-2.0, 2.0), (-2.8, 2.8), (-0.9, 3.1)),
    home_rad=(0.0, -1.96, 0.0, 3.15),
    tool_offset_m=(0.0, 0.0, 0.51),
    tool_axis=(0.0, 0.0, 1.0),
    ik_seed_rad=(0.0, 0.8, 0.0, 1.8),
)

#: The 7-DOF WAM with its wrist (libbarrett ``wam7w.conf``); a hand and finger of 0.2 m along
#: the toolplate's z, which is the last frame's −y (the toolplate row is ``Rx(π/2)``).
WAM7 = ArmPreset(
    name="wam7",
    links=(
        *_ARM4,
        DHLink(0.0, -_HALF_PI, 0.3),  # wrist yaw (forearm, 0.3 m)
        DHLink(0.0, _HALF_PI, 0.0),  # wrist pitch
        DHLink(0.0, -_HALF_PI, 0.0609),  # wrist twist
    ),
    j2mp=(
        (-42.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        (0.0, 28.25, -16.8155, 0.0, 0.0, 0.0, 0.0),
        (0.0, -28.25, -16.8155, 0.0, 0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0, -18.0, 0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0, 0.0, 9.7, -9.7, 0.0),
        (0.0, 0.0, 0.0, 0.0, 9.7, 9.7, 0.0),
        (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -14.93),
    ),
    limits_rad=((-2.6, 2.6), (-2.0, 2.0), (-2.8, 2.8), (-0.9, 3.1), (-4.55, 1.25),
                (-1.57, 1.57), (-2.95, 2.95)),
    home_rad=(0.0, -1.9, 0.0, 3.14, 0.0, 0.0, 0.0),
    tool_offset_m=(0.0, -0.2, 0.0),
    tool_axis=(0.0, -1.0, 0.0),
    ik_seed_rad=(0.0, 0.6, 0.0, 1.6, 0.0, 0.9, 0.0),
)


def _dh(link: DHLink, theta: float) -> FloatArray:
    ct, st = math.cos(theta + link.theta_offset_rad), math.sin(theta + link.theta_offset_rad)
    ca, sa = math.cos(link.alpha_rad), math.sin(link.alpha_rad)
    return np.array([
        [ct, -st * ca, st * sa, link.a_m * ct],
        [st, ct * ca, -ct * sa, link.a_m * st],
        [0.0, sa, ca, link.d_m],
        [0.0, 0.0, 0.0, 1.0],
    ])


@dataclass(frozen=True)
class IKResult:
    """A solution: the joints, the position error left (m), whether it converged."""

    q: FloatArray
    error_m: float
    ok: bool


class SerialArm:
    """A revolute serial arm placed in the map frame.

    Parameters
    ----------
    links : sequence of DHLink
    tool_offset_m : (3,) array_like
        The fingertip in the last joint's frame.
    limits_rad : sequence of (low, high)
    base_position_m : (3,) array_like
        The base frame's origin (the shoulder) in the map frame.
    base_yaw_rad : float
        Rotation of the base frame about the map's z axis.
    tool_axis : (3,) array_like
        The direction, in the last joint's frame, that should point down (a preference).
    """

    def __init__(
        self,
        links: Sequence[DHLink],
        tool_offset_m: ArrayLike,
        limits_rad: Sequence[tuple[float, float]],
        base_position_m: ArrayLike = (0.0, 0.0, 0.0),
        base_yaw_rad: float = 0.0,
        tool_axis: ArrayLike = (0.0, 0.0, 1.0),
    ) -> None:
        self.links = tuple(links)
        self.n = len(self.links)
        if len(limits_rad) != self.n:
            raise ValueError(f"{len(limits_rad)} joint limits for {self.n} joints")
        self.limits = np.array(limits_rad, dtype=np.float64)
        if np.any(self.limits[:, 1] <= self.limits[:, 0]):
            raise ValueError("each joint limit needs low < high")
        self.tool = np.append(np.asarray(tool_offset_m, dtype=np.float64), 1.0)
        axis = np.asarray(tool_axis, dtype=np.float64)
        self.tool_axis = axis / np.linalg.norm(axis)
        c, s = math.cos(base_yaw_rad), math.sin(base_yaw_rad)
        self.base = np.array([[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0],
                              [0.0, 0.0, 0.0, 1.0]])
        self.base[:3, 3] = np.asarray(base_position_m, dtype=np.float64)

    # --- forward ----------------------------------------------------------------------------

    def frames(self, q: ArrayLike) -> list[FloatArray]:
        """The base and every joint frame in the map frame: ``n + 1`` 4×4 transforms."""
        angles = np.asarray(q, dtype=np.float64)
        out = [self.base]
        t = self.base
        for link, theta in zip(self.links, angles.tolist(), strict=True):
            t = t @ _dh(link, theta)
            out.append(t)
        return out

    def forward(self, q: ArrayLike) -> FloatArray:
        """The fingertip's position (3,) in the map frame."""
        return (self.frames(q)[-1] @ self.tool)[:3]

    def link_points(self, q: ArrayLike) -> FloatArray:
        """The joint frames' origins after the base, and the fingertip: ``(n + 1, 3)``."""
        frames = self.frames(q)
        return np.vstack([*(f[:3, 3] for f in frames[1:]), (frames[-1] @ self.tool)[:3]])

    def jacobian(self, q: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
        """``(J, p, axis, z)``: the fingertip's position Jacobian (3, n), the fingertip (3,),
        the tool axis (3,) and the joint axes (n, 3), all in the map frame."""
        frames = self.frames(q)
        p = (frames[-1] @ self.tool)[:3]
        z = np.vstack([f[:3, 2] for f in frames[:-1]])
        o = np.vstack([f[:3, 3] for f in frames[:-1]])
        jac = np.cross(z, p - o).T
        axis = frames[-1][:3, :3] @ self.tool_axis
        return jac, p, axis, z

    def within_limits(self, q: ArrayLike, margin_rad: float = 0.0) -> NDArray[np.bool_]:
        """Whether each row of joints ``(..., n)`` is within every limit (less a margin)."""
        a = np.asarray(q, dtype=np.float64)
        return np.all((a >= self.limits[:, 0] + margin_rad)
                      & (a <= self.limits[:, 1] - margin_rad), axis=-1)

    # --- inverse ----------------------------------------------------------------------------

    def solve(
        self,
        target: ArrayLike,
        seed: ArrayLike,
        *,
        tolerance_m: float = 1e-5,
        max_iterations: int = 200,
        min_iterations: int = 0,
        damping: float = 0.02,
        pointing_gain: float = 0.5,
        centering_gain: float = 0.05,
        max_step_rad: float = 0.2,
    ) -> IKResult:
        """Joints that put the fingertip at ``target`` (3,), by DLS from ``seed``.

        Each iteration takes ``dq = Jᵀ (J Jᵀ + λ² I)⁻¹ e`` plus the null-space projection of
        the secondary objectives' descent (tool axis down, joints centred), clipped to
        ``max_step_rad``; at least ``min_iterations`` run (to let the secondary objectives
        settle), at most ``max_iterations``.
        """
        goal = np.asarray(target, dtype=np.float64)
        q = np.array(seed, dtype=np.float64)
        mid = self.limits.mean(axis=1)
        span = self.limits[:, 1] - self.limits[:, 0]
        down = np.array([0.0, 0.0, -1.0])
        eye3 = np.eye(3)
        error = math.inf
        for i in range(max_iterations):
            jac, p, axis, z = self.jacobian(q)
            e = goal - p
            error = float(np.linalg.norm(e))
            if error <= tolerance_m and i >= min_iterations:
                break
            jjt = jac @ jac.T
            dq = jac.T @ np.linalg.solve(jjt + damping**2 * eye3, e)
            if pointing_gain or centering_gain:
                # d(axis)/dq_i = z_i × axis: descend 0.5 |axis − down|².
                grad = np.cross(z, axis) @ (axis - down) * pointing_gain
                grad += centering_gain * (q - mid) / span**2
                pinv = jac.T @ np.linalg.solve(jjt + 1e-9 * eye3, eye3)
                dq -= grad - pinv @ (jac @ grad)
            biggest = float(np.max(np.abs(dq)))
            if biggest > max_step_rad:
                dq *= max_step_rad / biggest
            q += dq
        return IKResult(q, error, error <= tolerance_m)

    def solve_line(
        self, points: ArrayLike, seed: ArrayLike, *, tolerance_m: float = 1e-5, **kwargs: float
    ) -> tuple[FloatArray, FloatArray]:
        """Joints for each point ``(m, 3)``, each solved from the previous one:
        ``(q (m, n), errors (m,))``. The first point that does not converge ends the march
        (the rest: the seed's joints and an infinite error)."""
        pts = np.asarray(points, dtype=np.float64)
        q = np.asarray(seed, dtype=np.float64)
        qs = np.tile(q, (len(pts), 1))
        errors = np.full(len(pts), np.inf)
        for i, point in enumerate(pts):
            result = self.solve(point, q, tolerance_m=tolerance_m, **kwargs)  # type: ignore[arg-type]
            q = result.q
            qs[i] = q
            errors[i] = result.error_m
            if not result.ok:
                break
        return qs, errors


class Transmission:
    """Joint angles ↔ puck (motor) encoder counts: ``counts = j2mp @ q * CTS / 2π``.

    The counts are those of pucks zeroed as libbarrett zeroes them (the arm's counters read
    ``j2mp @ q`` in motor radians); the robot does not zero the arm.

    Parameters
    ----------
    j2mp : (n, n) array_like
        Joint to motor radians.
    counts_per_rev : (n,) array_like
        Each puck's ``CTS``.
    """

    def __init__(self, j2mp: ArrayLike, counts_per_rev: ArrayLike) -> None:
        self.j2mp = np.asarray(j2mp, dtype=np.float64)
        n = self.j2mp.shape[0]
        if self.j2mp.shape != (n, n) or abs(np.linalg.det(self.j2mp)) < 1e-9:
            raise ValueError(f"j2mp must be an invertible square matrix, got {self.j2mp.shape}")
        self.mp2j = np.linalg.inv(self.j2mp)
        self.cts = np.broadcast_to(np.asarray(counts_per_rev, dtype=np.float64), (n,)).copy()
        if np.any(self.cts <= 0):
            raise ValueError(f"counts per revolution must be positive, got {self.cts}")

    def counts(self, q: ArrayLike) -> NDArray[np.int64]:
        """Joint angles (n,) → the nearest motor counts (n,)."""
        motor = self.j2mp @ np.asarray(q, dtype=np.float64)
        return np.rint(motor * self.cts / (2.0 * math.pi)).astype(np.int64)

    def joints(self, counts: ArrayLike) -> FloatArray:
        """Motor counts (n,) → joint angles (n,)."""
        motor = np.asarray(counts, dtype=np.float64) * (2.0 * math.pi) / self.cts
        return np.asarray(self.mp2j @ motor, dtype=np.float64)
