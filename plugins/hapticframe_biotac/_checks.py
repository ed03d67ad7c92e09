"""Checks of the BioTac sensor that ``validate`` runs (import-light: no numpy)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

from hapticframe import Size, ValidationContext

__all__ = ["check"]

#: Values a frame holds once decoded: pac (22), electrodes (19; 24 on the SP), pdc, tac,
#: tdc, position (2), contact, and a validity flag per channel, rounded up.
_VALUES_PER_FRAME = 64
#: Frames a second (the BioTac's 100 Hz frame rate).
_FRAME_RATE_HZ = 100.0
#: How far a synthetic trial's fingertip travels (its ~12.5 cm stroke).
_TRIAL_TRAVEL_M = 0.125


def check(config: Any, context: ValidationContext) -> Iterator[Size]:
    """Declare what one read, and the whole source read at once (``read_all``, training),
    hold."""
    frame_bytes = 8.0 * _VALUES_PER_FRAME
    yield Size("frames_per_read", f"{config.frames_per_read} frames a read",
               bytes=frame_bytes * config.frames_per_read, remedy="lower frames_per_read")
    per_trial = (_TRIAL_TRAVEL_M / config.speed_m_per_s + config.trial_gap_s) * _FRAME_RATE_HZ
    trials = config.n_trials if config.source == "synthetic" else 0
    yield Size("n_trials", f"{trials} synthetic trials of about {per_trial:.0f} frames each, "
               "read whole (read_all, training)", bytes=frame_bytes * trials * per_trial,
               remedy="fewer n_trials")
    frames = config.emulator_frames if config.source == "spi" else None
    yield Size("emulator_frames",
               f"the whole emulated SPI stream of {frames or 0} frames, read whole (read_all, "
               "training)", bytes=frame_bytes * (frames or 0),
               remedy="fewer emulator_frames (null: an endless stream, never read whole)")
