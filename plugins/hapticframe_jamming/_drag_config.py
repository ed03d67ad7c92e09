"""Config of the drag-ratio jamming classifier (import-light)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig

from ._config import check_filter

__all__ = ["DragRatioJammingConfig"]


class DragRatioJammingConfig(PluginConfig):
    """Jamming and contact in units of the movement's own free drag.

    Each movement's free drag ``b`` is estimated online from its own force: once the
    start-up transient has settled (the median filtered force over the last
    ``settle_window_s`` no longer exceeds the median over the window before by more than
    ``settle_fraction``), ``b`` is that median; afterwards it tracks the force slowly
    (time constant ``tracking_time_s``) while there is no evidence of jamming, and is frozen
    while there is. Jamming is a one-sided CUSUM on the log-ratio ``z = log(f / b)``:
    ``S <- max(0, S + (z - drift) dt)`` flags jamming above ``cusum_threshold``. Contact is
    the thesis's AND rule (Figure 3.4) on the ratio ``f / b`` and its rate ``f' / b``. Every
    threshold is in units of the drag, so the same settings hold at every depth and in sands
    whose drag differs tenfold; ``fit`` (``hapticframe train``) places them so that free
    raking raises at most ``false_alarms_per_m`` alarms per metre (docs/benchmarks.md).
    """

    force_channel: str = Field("force_n", description="Input channel holding the force (N).")
    force_component: Literal["magnitude", "0", "1", "2"] = Field(
        "magnitude",
        description="What is read of the force: 'magnitude' (the Euclidean norm of all its "
        "components: frame-free, and it counts an object's sideways push too), or the "
        "absolute value of one component by index (e.g. '0' for a tool-frame sensor's axis "
        "along the motion).",
    )
    sample_rate_hz: float | None = Field(
        None, gt=0, le=100_000,
        description="Rate the low-pass filter is designed for; None takes the input sensor's "
        "channel rate, or 100 Hz without an input.",
    )
    cutoff_hz: float = Field(3.0, gt=0, le=10_000, description="Butterworth low-pass cutoff.")
    filter_order: int = Field(2, ge=1, le=4, description="Butterworth filter order.")
    restart_after_gap_s: float = Field(
        0.05, gt=0, le=3600,
        description="A valid force more than this long after the previous valid one restarts "
        "the filter at rest on it (the drag estimate is kept).",
    )
    settle_window_s: float = Field(
        0.25, gt=0, le=60,
        description="Window of the start-up test and of the initial drag estimate (a median).",
    )
    settle_fraction: float = Field(
        0.04, gt=0, le=10,
        description="The start-up has settled when the last window's median force exceeds the "
        "window before's by at most this fraction.",
    )
    warmup_min_s: float = Field(
        1.1, ge=0, le=600,
        description="The drag is not estimated before this much of the movement has passed "
        "(1.1 s: 5.5 cm at 5 cm/s, the engine world's start-up, which pauses on the way); "
        "fit chooses it among 0.5, 0.8, 1.1 and 1.5 s.",
    )
    warmup_max_s: float = Field(
        2.5, gt=0, le=600,
        description="At the latest here the drag estimate is taken, settled or not.",
    )
    tracking_time_s: float = Field(
        1.5, gt=0, le=3600,
        description="Time constant of the drag estimate's slow tracking while the CUSUM is at "
        "zero (no evidence of jamming); frozen otherwise.",
    )
    carry_drag: bool = Field(
        True,
        description="Judge a movement's warm-up against the largest drag of the run's earlier "
        "movements (its CUSUM and contact rule), so that a movement starting next to an "
        "object is not blind until its own drag is estimated; false: free until then.",
    )
    min_drag_n: float = Field(
        0.05, gt=0, le=1e4, allow_inf_nan=False,
        description="Floor of the drag estimate (force units): a drag near zero would make "
        "every ratio huge.",
    )
    drift: float = Field(
        0.12, ge=0, le=10, allow_inf_nan=False,
        description="CUSUM allowance on the log-ratio: log(f/b) above it accumulates (0.12 is "
        "a force 13 % above the drag).",
    )
    cusum_threshold: float = Field(
        0.02, ge=0, le=1e3, allow_inf_nan=False,
        description="CUSUM level (log-ratio x seconds) above which jamming is flagged; 0 makes "
        "the rule a plain ratio threshold at exp(drift).",
    )
    cusum_scale: float = Field(
        0.01, gt=0, le=1e3, allow_inf_nan=False,
        description="Softness of the CUSUM threshold: CUSUM per unit of logit.",
    )
    contact_ratio: float = Field(
        3.0, ge=0, le=1e6, allow_inf_nan=False,
        description="Force / drag above which contact is possible.",
    )
    contact_ratio_rate_per_s: float = Field(
        10.0, ge=-1e6, le=1e6, allow_inf_nan=False,
        description="Force rate / drag (1/s) above which contact is possible.",
    )
    ratio_scale: float = Field(
        0.25, gt=0, le=1e4, allow_inf_nan=False,
        description="Softness of the contact ratio threshold.",
    )
    ratio_rate_scale_per_s: float = Field(
        2.0, gt=0, le=1e6, allow_inf_nan=False,
        description="Softness of the contact ratio-rate threshold.",
    )
    false_alarms_per_m: float = Field(
        1.0, gt=0, le=1e4, allow_inf_nan=False,
        description="fit: the most alarm onsets per metre of free raking (after the drag "
        "estimate) that the fitted thresholds may raise on the recordings.",
    )
    speed_m_per_s: float = Field(
        0.05, gt=0, le=10, allow_inf_nan=False,
        description="fit: the recordings' raking speed, which turns their free time into the "
        "distance of the false-alarm budget.",
    )
    model_dir: str | None = Field(
        None,
        description="Directory written by save() (drag_ratio.json, e.g. by `hapticframe "
        "train`) to load at build time: its fitted thresholds replace the configured ones; "
        "its filter and drag estimate settings must equal this config's.",
    )

    @model_validator(mode="after")
    def _consistent(self) -> DragRatioJammingConfig:
        check_filter(self.cutoff_hz, self.sample_rate_hz)
        if self.warmup_min_s > self.warmup_max_s:
            raise ValueError(
                f"warmup_min_s ({self.warmup_min_s}) must not exceed warmup_max_s "
                f"({self.warmup_max_s})"
            )
        return self
