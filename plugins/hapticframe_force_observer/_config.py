"""Config of the force observer feature extractor (import-light)."""

from __future__ import annotations

import math

from pydantic import Field, model_validator

from hapticframe import PluginConfig
from hapticframe.filters import MIN_CUTOFF_RATIO

__all__ = ["ForceObserverConfig"]


class ForceObserverConfig(PluginConfig):
    """Removes the end effector's inertial and gravitational load from a wrist force (Eq. 3.10).

    The parameters ``m_e``, ``R`` and ``ε`` come from ``model_dir`` (what ``hapticframe
    train`` saved after fitting free motions in air), or inline from ``mass_kg``,
    ``imu_rotation_wxyz`` and ``bias_n``; without either, zero mass, the identity and zero
    bias: the observer passes the filtered force through.
    """

    force_channel: str = Field("force_n", description="Channel of the force sensor input (N).")
    acceleration_channel: str = Field(
        "acceleration_m_per_s2",
        description="Channel of the IMU input: specific force (raw accelerometer, gravity "
        "included) in m/s², in the IMU frame.",
    )
    max_age_s: float = Field(
        0.1,
        gt=0,
        allow_inf_nan=False,
        le=10.0,
        description="Sample-and-hold alignment of the IMU onto the force sensor's timestamps: "
        "an IMU sample older than this makes the output sample invalid.",
    )
    sample_rate_hz: float | None = Field(
        None,
        gt=0,
        allow_inf_nan=False,
        le=100_000,
        description="Rate the low-pass filter is designed for; None takes the force input's "
        "channel rate, or 100 Hz without an input.",
    )
    cutoff_hz: float = Field(
        10.0, gt=0, allow_inf_nan=False, le=10_000,
        description="Butterworth low-pass cutoff frequency."
    )
    filter_order: int = Field(2, ge=1, le=8, description="Butterworth filter order.")
    model_dir: str | None = Field(
        None,
        description="Directory written by save() (model.json + model.npz) to load m_e, R and "
        "ε from at build time; excludes the inline parameters.",
    )
    mass_kg: float | None = Field(
        None,
        allow_inf_nan=False,
        ge=0, le=1000,
        description="m_e: mass beyond the force sensor (a gain in N per m/s²); None: 0.",
    )
    imu_rotation_wxyz: tuple[float, float, float, float] | None = Field(
        None,
        description="R: rotation sensor ← IMU as a unit quaternion (w, x, y, z); None: identity.",
    )
    bias_n: tuple[float, float, float] | None = Field(
        None, description="ε: the force sensor's constant offset in N; None: zero."
    )

    @model_validator(mode="after")
    def _consistent(self) -> ForceObserverConfig:
        if self.sample_rate_hz is not None and self.cutoff_hz >= self.sample_rate_hz / 2:
            raise ValueError(
                f"cutoff_hz ({self.cutoff_hz}) must be below the Nyquist frequency "
                f"({self.sample_rate_hz / 2} Hz)"
            )
        # The filter at the rate it is designed for (the input's, or 100 Hz by default).
        rate = self.sample_rate_hz if self.sample_rate_hz is not None else 100.0
        if self.cutoff_hz < MIN_CUTOFF_RATIO * rate:
            raise ValueError(
                f"cutoff_hz ({self.cutoff_hz:.4g}) must be at least {MIN_CUTOFF_RATIO:g} of "
                f"the sample rate ({MIN_CUTOFF_RATIO * rate:.4g} Hz at {rate:g} Hz): below, "
                "the low-pass filter's coefficients lose their precision (NaN forces)"
            )
        inline = [
            name for name in ("mass_kg", "imu_rotation_wxyz", "bias_n")
            if getattr(self, name) is not None
        ]
        if self.model_dir is not None and inline:
            raise ValueError(
                f"model_dir provides m_e, R and ε; do not also set {', '.join(inline)}"
            )
        values = [*(self.imu_rotation_wxyz or ()), *(self.bias_n or ())]
        if not all(math.isfinite(v) for v in values):
            raise ValueError("imu_rotation_wxyz and bias_n must be finite")
        if self.imu_rotation_wxyz is not None:
            norm = math.sqrt(sum(v * v for v in self.imu_rotation_wxyz))
            if abs(norm - 1.0) > 1e-3:
                raise ValueError(
                    "imu_rotation_wxyz must be a unit quaternion (w, x, y, z), its norm is "
                    f"{norm:.6g}"
                )
        return self
