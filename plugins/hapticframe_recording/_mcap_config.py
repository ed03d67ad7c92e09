"""Config of the ``recording`` sensor (import-light: pydantic and hapticframe only)."""

from __future__ import annotations

from pydantic import Field, model_validator

from hapticframe import PluginConfig

__all__ = ["McapRecordingConfig"]


class McapRecordingConfig(PluginConfig):
    """Feed one recorded sensor channel of a ``run.mcap`` into a pipeline again.

    The samples keep their recorded timestamps; channels, units and rates are the recorded
    ones. Relative paths are taken from the directory ``hapticframe`` runs in.
    """

    file: str | None = Field(
        None,
        min_length=1,
        description="A run.mcap (a run's, a recovered one or an imported bag's), or the "
        "run's directory (its run.mcap, or the one a killed run left in its staging folder).",
    )
    topic: str | None = Field(
        None,
        description="The recorded channel to read (hapticframe.SampleBatch messages); None "
        "takes /sensor/<this component's id>.",
    )
    pace: bool = Field(
        False,
        description="Deliver the samples in real time by their timestamps; False delivers "
        "them as fast as the run reads.",
    )
    demo: bool = Field(
        False,
        description="Read a small built-in recording (three messages of a 2-D force at "
        "100 Hz) instead of a file: for the conformance kit and tutorials.",
    )
    tare_frames: int = Field(
        0,
        ge=0,
        le=100_000,
        description="Subtract from each tared channel its mean over the recording's first "
        "tare_frames samples (resting frames), causally: sample k < tare_frames uses the "
        "samples so far; invalid samples stay out of the mean. The biotac sensor's replay "
        "tares the same way (its tare_frames), so a BioTac bag imported with import-bag and a "
        "CSV of the same frames give the same features. 0 (default): the recorded values.",
    )
    tare_channels: tuple[str, ...] | None = Field(
        None,
        min_length=1,
        description="Channels the tare applies to; None tares every channel (name them when "
        "the recording also holds ground truth such as position_m or contact).",
    )

    @model_validator(mode="after")
    def _one_source(self) -> McapRecordingConfig:
        if self.demo == (self.file is not None):
            raise ValueError("give either 'file' (a run.mcap or a run directory) or "
                             "'demo: true'")
        if self.tare_channels is not None and not self.tare_frames:
            raise ValueError("tare_channels needs tare_frames of at least 1")
        return self
