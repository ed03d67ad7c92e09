"""Config model of the BioTac sensor (import-light: pydantic and hapticframe only)."""

from __future__ import annotations

import re
from typing import Literal

from pydantic import Field, field_validator, model_validator

from hapticframe import PluginConfig

__all__ = ["BioTacSensorConfig"]

_BACKEND_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]{0,63}$")


class BioTacSensorConfig(PluginConfig):
    """A SynTouch BioTac (or BioTac SP) fingertip: one row per frame of raw 12-bit counts.

    Three sources: ``synthetic`` trials of the granular-media generator (with ground truth),
    ``replay`` of a recording (the project's ``.npz`` format or a BioTac ``.csv``), and ``spi``
    words decoded from an SPI-batch backend (``emulator`` without hardware).
    """

    source: Literal["synthetic", "replay", "spi"] = Field(
        "synthetic",
        description="Where frames come from: the synthetic generator, a recording, or the SPI "
        "word stream.",
    )
    variant: Literal["biotac", "biotac_sp"] = Field(
        "biotac",
        description="BioTac (44-word frame: 22 pac, 19 electrodes, 100 Hz) or BioTac SP (54-word "
        "frame: 27 pac, 24 electrodes, about 81.5 Hz).",
    )
    frames_per_read: int = Field(1, ge=1, le=10_000, description="Frames delivered by each read().")

    # -- replay ------------------------------------------------------------------------------
    path: str | None = Field(
        None, description="Replay: the recording, a hapticframe .npz, a BioTac .csv file or a "
        "Penn BOLT .h5 file (with bolt_trial and bolt_finger)."
    )
    bolt_trial: str | None = Field(
        None, min_length=1,
        description="Replay of a BOLT .h5 file: the trial (HDF5 group) to replay, e.g. "
        "'cork_pdc100_1cm_01'.",
    )
    bolt_finger: Literal[0, 1] = Field(
        0, description="Replay of a BOLT .h5 file: finger_0 or finger_1 of the PR2 gripper."
    )

    # -- synthetic ---------------------------------------------------------------------------
    medium: Literal[
        "poppy_seed", "plastic_pellets", "bbs", "pine_beads", "cottonwood_beads"
    ] = Field(
        "poppy_seed", description="Synthetic: the granular medium (Table 2.1 of the thesis)."
    )
    speed_m_per_s: float = Field(
        0.04,
        ge=0.005,
        le=0.2,
        description="Synthetic: fingertip speed (0.04 or 0.02 in the thesis).",
    )
    orientation_deg: float = Field(
        0.0, ge=-45, le=45, description="Synthetic: fingertip orientation (0 or 20 in the thesis)."
    )
    object_offset_m: float = Field(
        0.0,
        ge=-0.05,
        le=0.05,
        description="Synthetic: object offset along the path (0 or 0.035 in the thesis).",
    )
    has_object: bool = Field(
        True, description="Synthetic: whether a buried object lies on the path."
    )
    fingertip_depth_m: float = Field(
        0.05, ge=0.01, le=0.12, description="Synthetic: fingertip depth below the surface."
    )
    dataset: Literal["single", "training", "robustness"] = Field(
        "single",
        description="Synthetic: 'single' repeats the trial described here n_trials times; "
        "'training' (750 trials) and 'robustness' (375) are the thesis's sets, cut to n_trials.",
    )
    n_trials: int = Field(
        1, ge=1, le=100_000, description="Synthetic: trials generated one after another."
    )
    trial_gap_s: float = Field(
        0.5,
        gt=0,
        le=3600,
        description="Synthetic: time between the last frame of a trial and the first of the next.",
    )

    tare_frames: int = Field(
        0,
        ge=0,
        le=10_000,
        description="Synthetic and replay: subtract from every channel its mean over the first "
        "tare_frames frames of each trial (recording), causally (frame k < tare_frames uses the "
        "frames so far), as BioTac users zero the sensor before a trial; 0 (default) delivers raw "
        "12-bit counts. The perception benchmark uses 10 (100 ms) with tare_source 'air'.",
    )
    tare_source: Literal["trial_start", "air"] = Field(
        "trial_start",
        description="What the tare averages: 'trial_start', the first tare_frames frames of each "
        "trial or recording (for a recording that starts in open air, that is the usual zeroing); "
        "'air' (synthetic source only), tare_frames frames of the fingertip at rest in open air "
        "just before each trial, as users zero a BioTac before lowering it into the media.",
    )

    # -- spi ---------------------------------------------------------------------------------
    spi_backend: str = Field(
        "emulator",
        description="SPI: 'emulator', or the name of an adapter backend that an installed "
        "package registers in the 'hapticframe.biotac_spi' entry-point group (a factory called "
        "as factory(variant) that returns an SpiBatchBackend). Never an import path.",
    )
    emulator_frames: int | None = Field(
        None,
        ge=0,
        le=1_000_000_000,
        description="SPI emulator: end after this many frames (None: endless resting signal).",
    )
    parity_error_rate: float = Field(
        0.0, ge=0, le=1, description="SPI emulator: probability per word of a parity error."
    )
    stale_word_rate: float = Field(
        0.0, ge=0, le=1, description="SPI emulator: probability per word of a stale ('E-') word."
    )
    dropped_frame_rate: float = Field(
        0.0, ge=0, le=1, description="SPI emulator: probability per frame that it is lost."
    )
    jitter_s: float = Field(
        0.0005,
        ge=0,
        lt=0.005,
        description="SPI emulator: late reporting of each transfer's completion time, up to this.",
    )
    on_dropped_frame: Literal["mark", "skip"] = Field(
        "mark",
        description="SPI: deliver a dropped frame as a row holding the last values with every "
        "channel invalid ('mark', keeps a regular grid) or leave it out ('skip').",
    )

    @field_validator("spi_backend")
    @classmethod
    def _backend_name(cls, value: str) -> str:
        if not _BACKEND_NAME.match(value):
            raise ValueError(
                f"spi_backend must be a backend name such as 'emulator' (letters, digits, '_' "
                f"and '-'), not {value!r}; backends are registered by name, never by import path"
            )
        return value

    @model_validator(mode="after")
    def _source_needs(self) -> BioTacSensorConfig:
        if self.source == "replay":
            if not self.path:
                raise ValueError("source 'replay' needs a path to a .npz or .csv recording")
            if not self.path.lower().endswith((".npz", ".csv", ".h5")):
                raise ValueError(f"replay path {self.path!r} must end in .npz, .csv or .h5")
            if self.path.lower().endswith(".h5") and not self.bolt_trial:
                raise ValueError("a BOLT .h5 replay needs bolt_trial (the trial to replay)")
        if self.source == "spi" and self.tare_frames:
            raise ValueError("tare_frames applies to the synthetic and replay sources only")
        if self.tare_source == "air" and self.source != "synthetic":
            raise ValueError(
                "tare_source 'air' needs the synthetic source; a recording that starts in open "
                "air is zeroed in air by tare_source 'trial_start'"
            )
        if self.tare_source == "air" and not self.tare_frames:
            raise ValueError(
                "tare_source 'air' needs tare_frames of at least 1 (frames averaged in air)"
            )
        if self.source == "synthetic" and self.variant != "biotac":
            raise ValueError(
                "the synthetic generator models the 19-electrode BioTac only; use variant 'biotac'"
            )
        return self
