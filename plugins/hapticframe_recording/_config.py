"""Config of the ``trace-recording`` sensor (import-light: pydantic and hapticframe only)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from hapticframe import PluginConfig

__all__ = ["TraceRecordingConfig"]


class TraceRecordingConfig(PluginConfig):
    """Replay the channels of one sensor that a previous run recorded in its ``trace.npz``.

    Relative paths are taken from the directory ``hapticframe`` runs in. A recording is split
    into one trial per exploratory movement of the recorded robot, so that ``hapticframe
    train`` fits models per movement; optional labels (a simulator's ground truth, a lab's
    annotations) become one more channel.
    """

    path: str | None = Field(
        None,
        description="The trace.npz a run wrote, or the run's directory (its trace.npz).",
    )
    demo: bool = Field(
        False,
        description="Replay a small built-in recording (three movements of a 2-D force, one "
        "of them jamming) instead of a file: for the conformance kit and tutorials.",
    )
    component: str | None = Field(
        None,
        description="Id of the recorded sensor to replay; None takes the only sensor in the "
        "trace.",
    )
    channels: tuple[str, ...] | None = Field(
        None, min_length=1, description="Recorded channels to replay; None replays all."
    )
    robot: str | None = Field(
        None,
        description="Id of the recorded robot whose exploratory movements split the trials; "
        "None takes the only robot in the trace (no robot: one trial).",
    )
    split_movements: bool = Field(
        True,
        description="One recording (trial) per exploratory movement for training; False "
        "keeps the whole trace as one.",
    )
    labels: str | None = Field(
        None,
        description="An .npz holding 'timestamps_s' and a label array (e.g. the "
        "ground_truth.npz a sandbox run writes), or a run directory (its ground_truth.npz); "
        "the labels become the channel label_channel.",
    )
    labels_key: str = Field(
        "state",
        min_length=1,
        description="Name of the label array in the labels file (the sandbox: 'state', "
        "0 free, 1 jamming, 2 contact).",
    )
    label_channel: str = Field(
        "label",
        min_length=1,
        description="Channel the labels are delivered in: each sample gets the latest label "
        "at or before its time. Set run.label_channel to the same name for training.",
    )
    unlabelled: Literal["invalid", "drop"] = Field(
        "invalid",
        description="Samples before the first label: 'invalid' keeps them with a NaN label "
        "marked invalid, 'drop' leaves them out of the replay.",
    )
    samples_per_read: int = Field(
        10, ge=1, le=1_000_000, description="Recorded samples each streaming read() delivers."
    )
    rate_hz: float | None = Field(
        None,
        gt=0,
        le=1e6,
        allow_inf_nan=False,
        description="Channel rate to declare; None takes it from the recorded timestamps "
        "(one over the median sample period).",
    )

    @model_validator(mode="after")
    def _one_source(self) -> TraceRecordingConfig:
        if self.demo == (self.path is not None):
            raise ValueError("give either 'path' (a trace.npz or run directory) or 'demo: true'")
        if self.channels is not None and len(set(self.channels)) != len(self.channels):
            raise ValueError(f"channels repeats a name: {list(self.channels)}")
        if self.labels is not None and self.channels is not None:
            if self.label_channel in self.channels:
                raise ValueError(
                    f"label_channel {self.label_channel!r} is also a recorded channel to replay"
                )
        return self
