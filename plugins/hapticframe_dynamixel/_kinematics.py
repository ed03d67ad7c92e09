"""Kinematics of Dynamixel mechanisms (pure numpy): joint pulses ↔ fingertip pose.

A pose is ``(x, y, depth)`` in metres, depth below the free surface (depth = −z); joint
positions are servo pulses (4096 per turn, pulse 0 = 0 rad), as floats before rounding.

Two mechanisms, each a small frozen class over the functional layer below it:
:class:`Gantry` (three linear axes) and :class:`TwoLink` (a planar shoulder-elbow arm on a
vertical axis). Both offer ``inverse``, ``forward``, ``within_limits``, ``jacobian`` (of
the fingertip's world position ``(x, y, z)`` w.r.t. each servo's angle in radians) and
``problem`` (why a pose cannot be reached, or None). :func:`arm_forward`,
:func:`arm_inverse` and :func:`arm_jacobian` are the two-link arm's analytic kinematics;
:func:`line_problem` checks a whole straight line, not only its ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._control_table import PULSES_PER_REV

__all__ = [
    "Axis",
    "Gantry",
    "Joint",
    "TwoLink",
    "arm_forward",
    "arm_inverse",
    "arm_jacobian",
    "line_problem",
    "segment_distances",
]

_RAD_PER_PULSE = 2.0 * math.pi / PULSES_PER_REV


@dataclass(frozen=True)
class Axis:
    """One linear axis: ``coordinate = offset_m + metres_per_rad * pulses * 2π/4096``."""

    servo_id: int
    metres_per_rad: float
    offset_m: float = 0.0
    min_pulse: int = 0
    max_pulse: int = PULSES_PER_REV - 1

    def to_pulses(self, coordinate_m: float) -> float:
        return (coordinate_m - self.offset_m) / self.metres_per_rad / _RAD_PER_PULSE

    def to_metres(self, pulses: float) -> float:
        return self.offset_m + self.metres_per_rad * pulses * _RAD_PER_PULSE

    @property
    def metres_per_pulse(self) -> float:
        return self.metres_per_rad * _RAD_PER_PULSE


@dataclass(frozen=True)
class Gantry:
    """A Cartesian gantry: servos x, y and z (vertical; depth = −z), in that order."""

    x: Axis
    y: Axis
    z: Axis

    @property
    def axes(self) -> tuple[Axis, Axis, Axis]:
        return (self.x, self.y, self.z)

    @property
    def servos(self) -> tuple[Axis, Axis, Axis]:
        """The servos in joint order (each with ``servo_id``, ``min_pulse``, ``max_pulse``)."""
        return self.axes

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(axis.servo_id for axis in self.axes)

    def inverse(self, pose: ArrayLike) -> NDArray[np.float64]:
        """Poses ``(..., 3)`` (x, y, depth) → joint positions ``(..., 3)`` in pulses (float)."""
        p = np.asarray(pose, dtype=np.float64)
        out = np.empty_like(p)
        out[..., 0] = (p[..., 0] - self.x.offset_m) / self.x.metres_per_pulse
        out[..., 1] = (p[..., 1] - self.y.offset_m) / self.y.metres_per_pulse
        out[..., 2] = (-p[..., 2] - self.z.offset_m) / self.z.metres_per_pulse
        return out

    def forward(self, pulses: ArrayLike) -> NDArray[np.float64]:
        """Joint positions ``(..., 3)`` in pulses → poses ``(..., 3)`` (x, y, depth)."""
        q = np.asarray(pulses, dtype=np.float64)
        out = np.empty_like(q)
        out[..., 0] = self.x.offset_m + q[..., 0] * self.x.metres_per_pulse
        out[..., 1] = self.y.offset_m + q[..., 1] * self.y.metres_per_pulse
        out[..., 2] = -(self.z.offset_m + q[..., 2] * self.z.metres_per_pulse)
        return out

    def within_limits(self, pulses: ArrayLike) -> NDArray[np.bool_]:
        """Whether each row of joint positions ``(..., 3)`` lies within every axis's limits
        (after rounding to whole pulses, as they are sent)."""
        q = np.rint(np.asarray(pulses, dtype=np.float64))
        lo = np.array([a.min_pulse for a in self.axes], dtype=np.float64)
        hi = np.array([a.max_pulse for a in self.axes], dtype=np.float64)
        return np.all((q >= lo) & (q <= hi), axis=-1)

    def reach(self) -> tuple[tuple[float, float], tuple[float, float], tuple[float, float]]:
        """The (min, max) of x, y and depth that the joint limits allow."""
        lo = self.forward([a.min_pulse for a in self.axes])
        hi = self.forward([a.max_pulse for a in self.axes])
        return tuple(  # type: ignore[return-value]
            (float(min(a, b)), float(max(a, b))) for a, b in zip(lo, hi, strict=True)
        )

    def jacobian(self, pulses: ArrayLike) -> NDArray[np.float64]:
        """``(..., 3, 3)``: d(x, y, z)/d(servo angle in rad), world z up (constant)."""
        q = np.asarray(pulses, dtype=np.float64)
        jac = np.diag([a.metres_per_rad for a in self.axes]).astype(np.float64)
        return np.broadcast_to(jac, (*q.shape[:-1], 3, 3)).copy()

    def problem(self, poses: ArrayLike) -> str | None:
        """Why the first of ``poses (..., 3)`` cannot be reached, or None when all can."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        if not np.all(np.isfinite(p)):
            return f"the pose {_fmt(p[~np.all(np.isfinite(p), axis=1)][0])} is not finite"
        return _limits_problem(self.servos, p, self.inverse(p), ("x", "y", "z"))


# --- the planar two-link arm: functional layer --------------------------------------------


def arm_forward(angles_rad: ArrayLike, l1_m: float, l2_m: float,
                base_m: ArrayLike = (0.0, 0.0)) -> NDArray[np.float64]:
    """Joint angles ``(..., 2)`` (shoulder θ1 from the x axis, elbow θ2 relative to the
    upper arm, counter-clockwise seen from above) → fingertip ``(..., 2)`` in the plane."""
    q = np.asarray(angles_rad, dtype=np.float64)
    t1, t12 = q[..., 0], q[..., 0] + q[..., 1]
    out = np.empty_like(q)
    base = np.asarray(base_m, dtype=np.float64)
    out[..., 0] = base[0] + l1_m * np.cos(t1) + l2_m * np.cos(t12)
    out[..., 1] = base[1] + l1_m * np.sin(t1) + l2_m * np.sin(t12)
    return out


def arm_inverse(points_m: ArrayLike, l1_m: float, l2_m: float,
                base_m: ArrayLike = (0.0, 0.0), elbow: str = "right") -> NDArray[np.float64]:
    """Fingertip points ``(..., 2)`` → joint angles ``(..., 2)`` in rad, analytically.

    ``elbow`` picks the branch: ``"right"``, the elbow to the right of the line from the
    shoulder to the fingertip (seen from above, z up; θ2 ≥ 0), or ``"left"`` (θ2 ≤ 0).
    θ1 lies in (−2π, π]; the caller chooses the turn (see :meth:`Joint.to_pulses`).

    Raises
    ------
    ValueError
        Naming the first point that is not finite or lies outside the annulus
        ``|l1 − l2| ≤ r ≤ l1 + l2`` around the shoulder.
    """
    if elbow not in ("left", "right"):
        raise ValueError(f"elbow must be 'left' or 'right', got {elbow!r}")
    p = np.asarray(points_m, dtype=np.float64)
    base = np.asarray(base_m, dtype=np.float64)
    flat = p.reshape(-1, 2)
    finite = np.all(np.isfinite(flat), axis=1)
    if not np.all(finite):
        raise ValueError(f"the point {_fmt(flat[~finite][0])} is not finite")
    d = p - base
    r = np.hypot(d[..., 0], d[..., 1])
    inner, outer = abs(l1_m - l2_m), l1_m + l2_m
    # A relative slack: a point on the boundary (fully stretched, folded) is reachable.
    slack = 1e-12 * outer
    bad = ((r > outer + slack) | (r < inner - slack)).reshape(-1)
    if np.any(bad):
        point, dist = flat[bad][0], r.reshape(-1)[bad][0]
        raise ValueError(
            f"the point {_fmt(point)} is {dist:.4g} m from the shoulder at {_fmt(base)}: "
            f"the arm reaches {inner:.4g}...{outer:.4g} m (links {l1_m:g} m and {l2_m:g} m)")
    c2 = np.clip((r * r - l1_m * l1_m - l2_m * l2_m) / (2.0 * l1_m * l2_m), -1.0, 1.0)
    t2 = np.arccos(c2) * (1.0 if elbow == "right" else -1.0)
    t1 = np.arctan2(d[..., 1], d[..., 0]) - np.arctan2(l2_m * np.sin(t2),
                                                        l1_m + l2_m * np.cos(t2))
    return np.stack([t1, t2], axis=-1)


def arm_jacobian(angles_rad: ArrayLike, l1_m: float, l2_m: float) -> NDArray[np.float64]:
    """``(..., 2, 2)``: d(x, y)/d(θ1, θ2) of :func:`arm_forward`."""
    q = np.asarray(angles_rad, dtype=np.float64)
    t1, t12 = q[..., 0], q[..., 0] + q[..., 1]
    jac = np.empty((*q.shape[:-1], 2, 2))
    jac[..., 0, 0] = -l1_m * np.sin(t1) - l2_m * np.sin(t12)
    jac[..., 0, 1] = -l2_m * np.sin(t12)
    jac[..., 1, 0] = l1_m * np.cos(t1) + l2_m * np.cos(t12)
    jac[..., 1, 1] = l2_m * np.cos(t12)
    return jac


def segment_distances(a: ArrayLike, b: ArrayLike, c: ArrayLike) -> tuple[float, float]:
    """The least and greatest distance from point ``c`` to the segment ``a``–``b`` (2-D)."""
    a_, b_, c_ = (np.asarray(v, dtype=np.float64) for v in (a, b, c))
    ab = b_ - a_
    length2 = float(ab @ ab)
    s = 0.0 if length2 == 0.0 else float(np.clip((c_ - a_) @ ab / length2, 0.0, 1.0))
    nearest = float(np.linalg.norm(a_ + s * ab - c_))
    farthest = max(float(np.linalg.norm(a_ - c_)), float(np.linalg.norm(b_ - c_)))
    return nearest, farthest


def line_problem(kinematics: Gantry | TwoLink, start: ArrayLike, end: ArrayLike,
                 spacing_m: float = 5e-4) -> str | None:
    """Why the straight line of poses ``start``–``end`` (x, y, depth) cannot be followed,
    or None: the two-link arm's annulus is checked exactly, the joint limits at points
    ``spacing_m`` apart (and both ends)."""
    a = np.asarray(start, dtype=np.float64)
    b = np.asarray(end, dtype=np.float64)
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return f"the line {_fmt(a)} → {_fmt(b)} is not finite"
    if isinstance(kinematics, TwoLink):
        near, far = segment_distances(a[:2], b[:2], kinematics.base_m)
        inner, outer = kinematics.annulus_m
        slack = 1e-12 * outer
        if far > outer + slack or near < inner - slack:
            which = "beyond the arm's reach" if far > outer + slack else "too near the shoulder"
            return (f"the line {_fmt(a[:2])} → {_fmt(b[:2])} passes {which} (it lies "
                    f"{near:.4g}...{far:.4g} m from the shoulder at {_fmt(kinematics.base_m)};"
                    f" the arm reaches {inner:.4g}...{outer:.4g} m)")
    count = max(2, math.ceil(float(np.linalg.norm(b - a)) / spacing_m) + 1)
    samples = a + np.linspace(0.0, 1.0, count)[:, None] * (b - a)
    return kinematics.problem(samples)


def _limits_problem(servos: tuple[Axis | Joint, ...], poses: NDArray[np.float64],
                    pulses: NDArray[np.float64], names: tuple[str, ...]) -> str | None:
    q = np.rint(pulses)
    lo = np.array([s.min_pulse for s in servos], dtype=np.float64)
    hi = np.array([s.max_pulse for s in servos], dtype=np.float64)
    bad = (q < lo) | (q > hi)
    if not np.any(bad):
        return None
    row = int(np.argmax(np.any(bad, axis=1)))
    j = int(np.argmax(bad[row]))
    servo = servos[j]
    return (f"the pose {_fmt(poses[row])} (x, y, depth) needs the {names[j]} servo "
            f"(ID {servo.servo_id}) at pulse {int(q[row, j])}, beyond its limits "
            f"{servo.min_pulse}...{servo.max_pulse}")


def _fmt(values: ArrayLike) -> str:
    return "(" + ", ".join(f"{v:.4g}" for v in np.asarray(values, dtype=float).tolist()) + ")"


# --- the planar two-link arm: the mechanism -------------------------------------------------


@dataclass(frozen=True)
class Joint:
    """A revolute joint driven by one servo through a reduction:
    ``θ = offset_rad + servo_angle / gear_ratio`` (a negative ratio turns it the other way;
    ``|gear_ratio| ≥ 1``, so one joint angle is at most one servo position in 0...4095)."""

    servo_id: int
    gear_ratio: float = 1.0
    offset_rad: float = 0.0
    min_pulse: int = 0
    max_pulse: int = PULSES_PER_REV - 1

    def to_rad(self, pulses: ArrayLike) -> NDArray[np.float64]:
        return self.offset_rad + np.asarray(pulses, dtype=np.float64) * (
            _RAD_PER_PULSE / self.gear_ratio)

    def to_pulses(self, angle_rad: ArrayLike) -> NDArray[np.float64]:
        """The servo position (float pulses) for a joint angle, taking the turn (θ + 2πk)
        that lies nearest the middle of the limits (within them whenever one does)."""
        raw = (np.asarray(angle_rad, dtype=np.float64) - self.offset_rad) * (
            self.gear_ratio / _RAD_PER_PULSE)
        period = PULSES_PER_REV * abs(self.gear_ratio)
        middle = 0.5 * (self.min_pulse + self.max_pulse)
        return np.asarray(raw + np.round((middle - raw) / period) * period, dtype=np.float64)


@dataclass(frozen=True)
class TwoLink:
    """A planar shoulder-elbow arm in the map plane on a vertical (z) axis: servos shoulder,
    elbow and z, in that order.

    The shoulder's axis stands at ``base_m`` (x, y); θ1 is the upper arm's angle from the
    map's x axis, θ2 the forearm's relative to the upper arm (counter-clockwise seen from
    above). ``elbow`` picks the inverse's branch (see :func:`arm_inverse`).
    """

    shoulder: Joint
    elbow: Joint
    z: Axis
    l1_m: float
    l2_m: float
    base_m: tuple[float, float] = (0.0, 0.0)
    elbow_side: str = "right"

    @property
    def servos(self) -> tuple[Joint, Joint, Axis]:
        return (self.shoulder, self.elbow, self.z)

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(s.servo_id for s in self.servos)

    @property
    def annulus_m(self) -> tuple[float, float]:
        """The least and greatest distance from the shoulder that the fingertip reaches."""
        return abs(self.l1_m - self.l2_m), self.l1_m + self.l2_m

    def angles(self, pulses: ArrayLike) -> NDArray[np.float64]:
        """Joint positions ``(..., 3)`` in pulses → (θ1, θ2) ``(..., 2)`` in rad."""
        q = np.asarray(pulses, dtype=np.float64)
        return np.stack([self.shoulder.to_rad(q[..., 0]), self.elbow.to_rad(q[..., 1])], -1)

    def inverse(self, pose: ArrayLike) -> NDArray[np.float64]:
        """Poses ``(..., 3)`` (x, y, depth) → joint positions ``(..., 3)`` in pulses (float).
        Raises ValueError naming a point the arm cannot reach."""
        p = np.asarray(pose, dtype=np.float64)
        angles = arm_inverse(p[..., :2], self.l1_m, self.l2_m, self.base_m, self.elbow_side)
        out = np.empty_like(p)
        out[..., 0] = self.shoulder.to_pulses(angles[..., 0])
        out[..., 1] = self.elbow.to_pulses(angles[..., 1])
        out[..., 2] = (-p[..., 2] - self.z.offset_m) / self.z.metres_per_pulse
        return out

    def forward(self, pulses: ArrayLike) -> NDArray[np.float64]:
        """Joint positions ``(..., 3)`` in pulses → poses ``(..., 3)`` (x, y, depth)."""
        q = np.asarray(pulses, dtype=np.float64)
        out = np.empty_like(q)
        out[..., :2] = arm_forward(self.angles(q), self.l1_m, self.l2_m, self.base_m)
        out[..., 2] = -(self.z.offset_m + q[..., 2] * self.z.metres_per_pulse)
        return out

    def within_limits(self, pulses: ArrayLike) -> NDArray[np.bool_]:
        """Whether each row of joint positions lies within every servo's limits (rounded)."""
        q = np.rint(np.asarray(pulses, dtype=np.float64))
        lo = np.array([s.min_pulse for s in self.servos], dtype=np.float64)
        hi = np.array([s.max_pulse for s in self.servos], dtype=np.float64)
        return np.all((q >= lo) & (q <= hi), axis=-1)

    def jacobian(self, pulses: ArrayLike) -> NDArray[np.float64]:
        """``(..., 3, 3)``: d(x, y, z)/d(servo angle in rad), world z up."""
        q = np.asarray(pulses, dtype=np.float64)
        jac = np.zeros((*q.shape[:-1], 3, 3))
        arm = arm_jacobian(self.angles(q), self.l1_m, self.l2_m)
        jac[..., :2, 0] = arm[..., :, 0] / self.shoulder.gear_ratio
        jac[..., :2, 1] = arm[..., :, 1] / self.elbow.gear_ratio
        jac[..., 2, 2] = self.z.metres_per_rad
        return jac

    def problem(self, poses: ArrayLike) -> str | None:
        """Why the first of ``poses (..., 3)`` cannot be reached, or None when all can."""
        p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
        try:
            pulses = self.inverse(p)
        except ValueError as exc:
            return str(exc)
        if not np.all(np.isfinite(p[:, 2])):
            return "a depth is not finite"
        return _limits_problem(self.servos, p, pulses, ("shoulder", "elbow", "z"))
