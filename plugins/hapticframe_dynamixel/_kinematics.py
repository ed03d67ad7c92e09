"""Kinematics of Dynamixel mechanisms (pure numpy): joint pulses ↔ fingertip pose.

A pose is ``(x, y, depth)`` in metres, depth below the free surface (depth = −z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._control_table import PULSES_PER_REV

__all__ = ["Axis", "Gantry"]

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
