"""Config of the force/force-rate jamming classifier (import-light)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig
from hapticframe.filters import MIN_CUTOFF_RATIO

__all__ = ["ForceRateJammingConfig"]


class ForceRateJammingConfig(PluginConfig):
    """Thresholds in the 2-D space of filtered force and force rate (thesis Figure 3.4).

    A sample is "jamming" when both the filtered force magnitude and its rate exceed the
    jamming thresholds, and "contact" when both exceed the contact thresholds (contact wins).
    Probabilities are a softmax of the threshold margins divided by the scale fields. The
    defaults suit the ``sandbox`` simulator's defaults at 5 cm/s: its free-movement force
    rate stays below about 24 N/s, while jamming drives it to 40–55 N/s before contact. Rates
    scale with speed: recalibrate (``fit``) for other speeds or real sensors.
    """

    force_channel: str = Field(
        "force_n",
        description="Input channel holding the force (N), of any number of components: the "
        "classifier uses its magnitude |F|, the Euclidean norm over all of them (the "
        "sandbox's 2 in-plane components; a wrist sensor's or the force observer's 3, the "
        "vertical one included). Its thresholds are calibrated on the sandbox's in-plane "
        "force: recalibrate (fit) for a 3-axis force.",
    )
    sample_rate_hz: float | None = Field(
        None,
        gt=0,
        le=100_000,
        description="Rate the low-pass filter is designed for; None takes the input sensor's "
        "channel rate, or 100 Hz without an input.",
    )
    cutoff_hz: float = Field(
        3.0, gt=0, le=10_000,
        description="Butterworth low-pass cutoff frequency.",
    )
    filter_order: int = Field(2, ge=1, le=4, description="Butterworth filter order.")
    restart_after_gap_s: float = Field(
        0.05, gt=0, le=3600,
        description="A valid force more than this long after the previous valid "
        "one (a sensor replugged or resynchronising) restarts the filter at rest on it, so "
        "that the force's change during the gap does not read as a force rate.",
    )
    jamming_force_n: float = Field(
        6.0, allow_inf_nan=False, ge=-1e4, le=1e4,
        description="Filtered force above which jamming is possible."
    )
    jamming_rate_n_per_s: float = Field(
        27.0,
        allow_inf_nan=False,
        ge=-1e6, le=1e6, description="Filtered force rate above which jamming is possible.",
    )
    contact_force_n: float = Field(
        30.0,
        allow_inf_nan=False,
        ge=-1e4, le=1e4, description="Filtered force above which direct contact is possible.",
    )
    contact_rate_n_per_s: float = Field(
        70.0,
        allow_inf_nan=False,
        ge=-1e6, le=1e6, description="Filtered force rate above which direct contact is possible.",
    )
    force_scale_n: float = Field(
        2.0,
        gt=0,
        allow_inf_nan=False,
        le=1e4, description="Softness of the force thresholds: margin per unit of logit.",
    )
    rate_scale_n_per_s: float = Field(
        5.0,
        gt=0,
        allow_inf_nan=False,
        le=1e6, description="Softness of the rate thresholds: margin per unit of logit.",
    )

    calibration_force_floor: Literal["none", "free-drag"] = Field(
        "none",
        description="What `fit` (hapticframe train) may not place the jamming force threshold "
        "below: 'none', or 'free-drag', the largest steady free-sand drag of the recordings "
        "(per movement, the median filtered force over its free-labelled samples). Use "
        "'free-drag' where the free drag changes with depth: a threshold below it alarms in "
        "free sand and stops every deep movement early.",
    )

    model_dir: str | None = Field(
        None,
        description="Directory written by save() (thresholds.json, e.g. by `hapticframe "
        "train`) to load at build time: its four fitted thresholds replace the ones configured "
        "here; its filter (cutoff, order, sample rate) must equal this config's.",
    )

    @model_validator(mode="after")
    def _finite_nyquist(self) -> ForceRateJammingConfig:
        check_filter(self.cutoff_hz, self.sample_rate_hz)
        return self


def check_filter(cutoff_hz: float, sample_rate_hz: float | None) -> None:
    """Refuse a low-pass cutoff at or above Nyquist, or below ``MIN_CUTOFF_RATIO`` of the
    rate the filter is designed for (the sensor's, or 100 Hz by default), where its
    coefficients lose their precision and the classifier returns NaN probabilities."""
    if sample_rate_hz is not None and cutoff_hz >= sample_rate_hz / 2:
        raise ValueError(
            f"cutoff_hz ({cutoff_hz}) must be below the Nyquist frequency "
            f"({sample_rate_hz / 2} Hz)"
        )
    rate = sample_rate_hz if sample_rate_hz is not None else 100.0
    if cutoff_hz < MIN_CUTOFF_RATIO * rate:
        raise ValueError(
            f"cutoff_hz ({cutoff_hz:.4g}) must be at least {MIN_CUTOFF_RATIO:g} of "
            f"the sample rate ({MIN_CUTOFF_RATIO * rate:.4g} Hz at {rate:g} Hz): below, "
            "the low-pass filter's coefficients lose their precision and the classifier "
            "returns NaN probabilities"
        )
