"""The BioTac sensor component: frames from the synthetic generator, a recording or SPI words."""

from __future__ import annotations

import importlib
from collections.abc import Iterator, Mapping
from typing import Any

import numpy as np

from hapticframe.kinds import BuildContext, ChannelInfo, SampleBatch, Sensor

from ._backends import EMULATOR, backend_factory
from ._config import BioTacSensorConfig
from ._emulator import EmulatedBioTac, FaultPlan, SpiBatchBackend
from ._frame import BioTacFrames, FrameLayout, layout_for
from ._replay import load_recording
from ._tare import tare_reference
from ._wire import DecoderStats, WordStreamDecoder

__all__ = ["BioTacSensor", "tare_frames", "tare_in_air"]


def tare_frames(frames: BioTacFrames, n_frames: int) -> BioTacFrames:
    """One recording with each signal channel minus its causal tare reference.

    See :mod:`._tare`; invalid frames of a channel stay out of its reference. Returns
    ``frames`` itself when ``n_frames`` is 0.
    """
    if n_frames <= 0 or len(frames) == 0:
        return frames
    tared = {
        name: getattr(frames, name)
        - tare_reference(getattr(frames, name), n_frames, frames.channel_valid(name))
        for name in ("pac", "pdc", "tac", "tdc", "electrodes")
    }
    return BioTacFrames(
        frames.layout, frames.timestamps_s, tared["pac"], tared["pdc"], tared["tac"],
        tared["tdc"], tared["electrodes"], word_valid=frames.word_valid,
        frame_index=frames.frame_index, position_m=frames.position_m, contact=frames.contact,
    )


def tare_in_air(frames: BioTacFrames, air: Mapping[str, Any]) -> BioTacFrames:
    """One recording with each signal channel minus its mean over frames taken in open air.

    ``air`` maps ``pac``, ``pdc``, ``tac``, ``tdc`` and ``electrodes`` to the frames of a
    reading at rest before the recording (rows as in ``frames``), such as
    :func:`hapticframe_biotac._synthetic.open_air_frames` returns. pac is referred to the
    mean of all its samples (its AC-coupled centre).

    Raises
    ------
    ValueError
        If a channel of the reading is empty or not finite.
    """
    references: dict[str, Any] = {}
    for name in ("pac", "pdc", "tac", "tdc", "electrodes"):
        values = np.asarray(air[name], dtype=np.float64)
        if values.size == 0 or not np.all(np.isfinite(values)):
            raise ValueError(f"the open-air reading of {name} is empty or not finite")
        references[name] = values.mean() if name == "pac" else values.mean(axis=0)
    return BioTacFrames(
        frames.layout, frames.timestamps_s, frames.pac - references["pac"],
        frames.pdc - references["pdc"], frames.tac - references["tac"],
        frames.tdc - references["tdc"], frames.electrodes - references["electrodes"],
        word_valid=frames.word_valid, frame_index=frames.frame_index,
        position_m=frames.position_m, contact=frames.contact,
    )


class _FrameSource:
    """Frames handed out in order; subclasses say where they come from."""

    ground_truth = False
    contact_labels = False

    def next(self, count: int) -> BioTacFrames:
        raise NotImplementedError

    @property
    def exhausted(self) -> bool:
        return False

    def close(self) -> None:
        """Release what the source holds. Default: nothing."""


class _RecordedSource(_FrameSource):
    """A finite run of frames already in memory (a replayed recording)."""

    def __init__(self, frames: BioTacFrames) -> None:
        self.frames = frames
        self.ground_truth = frames.has_ground_truth
        self.contact_labels = frames.has_contact_labels
        self._position = 0

    def next(self, count: int) -> BioTacFrames:
        part = self.frames.select(slice(self._position, self._position + count))
        self._position += len(part)
        return part

    @property
    def exhausted(self) -> bool:
        return self._position >= len(self.frames)


class _SyntheticSource(_FrameSource):
    """Trials of the granular-media generator, one after another, on one increasing clock."""

    ground_truth = True
    contact_labels = True

    def __init__(
        self, config: BioTacSensorConfig, layout: FrameLayout, rng: np.random.Generator
    ) -> None:
        # Imported here: the generator is numpy-heavy and owned by the dataset module.
        synthetic = importlib.import_module("hapticframe_biotac._synthetic")
        self._generate = synthetic.generate_trial
        self._open_air_frames = synthetic.open_air_frames
        if config.dataset == "training":
            self._specs = list(synthetic.training_specs(rng))
        elif config.dataset == "robustness":
            self._specs = list(synthetic.robustness_specs(rng))
        else:
            self._specs = [synthetic.TrialSpec(
                medium=config.medium,
                speed_m_per_s=config.speed_m_per_s,
                orientation_deg=config.orientation_deg,
                object_offset_m=config.object_offset_m,
                has_object=config.has_object,
                fingertip_depth_m=config.fingertip_depth_m,
            )]
        self.layout = layout
        self.rng = rng
        self.trials_left = config.n_trials if config.dataset == "single" else min(
            config.n_trials or len(self._specs), len(self._specs))
        self._trial_number = 0
        self.gap_s = config.trial_gap_s
        self._buffer = BioTacFrames.empty(layout, ground_truth=True)
        self._last_time: float | None = None
        self._next_index = 0
        self.tare_frames = config.tare_frames
        self.tare_source = config.tare_source

    def _append_trial(self) -> None:
        spec = self._specs[self._trial_number % len(self._specs)]
        self._trial_number += 1
        trial = self._generate(spec, self.rng)
        t = np.asarray(trial.timestamps_s, dtype=np.float64)
        if self._last_time is not None and t.size:
            t = t - t[0] + self._last_time + self.gap_s
        n = t.size
        frames = BioTacFrames(
            self.layout, t, trial.pac, trial.pdc, trial.tac, trial.tdc, trial.electrodes,
            frame_index=self._next_index + np.arange(n),
            position_m=trial.position_m, contact=np.asarray(trial.contact, dtype=np.float64),
        )
        if self.tare_source == "air":
            air = self._open_air_frames(trial, self.tare_frames, self.rng)
            frames = tare_in_air(frames, air)
        else:
            frames = tare_frames(frames, self.tare_frames)
        self.trials_left -= 1
        if n:
            self._last_time = float(t[-1])
            self._next_index += n
            self._buffer = BioTacFrames.concatenate([self._buffer, frames])

    def next(self, count: int) -> BioTacFrames:
        while len(self._buffer) < count and self.trials_left > 0:
            self._append_trial()
        part = self._buffer.select(slice(0, count))
        self._buffer = self._buffer.select(slice(count, None))
        return part

    def next_trial(self) -> BioTacFrames:
        """The frames left of the trial being read, or the whole next trial."""
        if len(self._buffer) == 0 and self.trials_left > 0:
            self._append_trial()
        part = self._buffer
        self._buffer = part.select(slice(0, 0))
        return part

    @property
    def exhausted(self) -> bool:
        return self.trials_left <= 0 and len(self._buffer) == 0


class _SpiSource(_FrameSource):
    """Words from an SPI-batch backend through the decoder."""

    def __init__(
        self, config: BioTacSensorConfig, layout: FrameLayout, rng: np.random.Generator
    ) -> None:
        if config.spi_backend == EMULATOR:
            backend: Any = EmulatedBioTac(
                config.variant,
                rng,
                max_frames=config.emulator_frames,
                faults=FaultPlan(
                    parity_error_rate=config.parity_error_rate,
                    stale_word_rate=config.stale_word_rate,
                    dropped_frame_rate=config.dropped_frame_rate,
                ),
                jitter_s=config.jitter_s,
            )
        else:
            backend = backend_factory(config.spi_backend)(config.variant)
        if not isinstance(backend, SpiBatchBackend):
            raise TypeError(
                f"SPI backend {config.spi_backend!r} built {type(backend).__name__}, "
                "not an SpiBatchBackend"
            )
        self.backend: SpiBatchBackend = backend
        self.decoder = WordStreamDecoder(config.variant, on_dropped=config.on_dropped_frame)
        self.frame_words = layout.frame_words

    def next(self, count: int) -> BioTacFrames:
        data = self.backend.read_words(count * self.frame_words)
        return self.decoder.feed(data, self.backend.transfer_end_time_s)

    @property
    def exhausted(self) -> bool:
        return self.backend.exhausted

    def close(self) -> None:
        self.backend.close()


class BioTacSensor(Sensor):
    """A BioTac fingertip delivering one SampleBatch row per frame (see the package notes).

    Channels: ``pac`` (22,) [27 on the SP], ``pdc``, ``tac``, ``tdc`` (), ``electrodes`` (19,)
    [24 on the SP], all raw 12-bit counts, plus ground truth ``position_m`` (2,) and
    ``contact`` () from the synthetic source and labelled recordings. Every signal channel
    has a validity flag per row: False where one of its words failed parity, was stale or
    belongs to a dropped frame. ``rate_hz`` of every channel is the frame rate (pac's own
    sample rate is ``n_pac`` times that).
    """

    def __init__(self, config: BioTacSensorConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        self.layout = layout_for(config.variant)
        self._source: _FrameSource
        if config.source == "synthetic":
            self._source = _SyntheticSource(config, self.layout, context.rng)
        elif config.source == "replay":
            if (config.path or "").lower().endswith(".h5"):
                from ._bolt import load_bolt

                trials = load_bolt(config.path or "", [config.bolt_trial or ""])
                recording = trials[config.bolt_finger].recording
            else:
                recording = load_recording(config.path or "", config.variant)
            self.metadata = recording.metadata
            self._source = _RecordedSource(tare_frames(recording.frames, config.tare_frames))
        else:
            self._source = _SpiSource(config, self.layout, context.rng)
        self._channels = self.layout.channel_infos(
            ground_truth=self._source.ground_truth, contact=self._source.contact_labels)
        self._last_time = -np.inf

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def exhausted(self) -> bool:
        return self._source.exhausted

    @property
    def decoder_stats(self) -> DecoderStats | None:
        """Parity, stale and dropped-frame counters of the SPI source (None for other sources)."""
        return self._source.decoder.stats if isinstance(self._source, _SpiSource) else None

    def read_frames(self) -> BioTacFrames:
        """The next ``frames_per_read`` frames with per-word validity (none once exhausted)."""
        if self._source.exhausted:
            return BioTacFrames.empty(self.layout, ground_truth=self._source.ground_truth,
                                      contact=self._source.contact_labels)
        frames = self._source.next(self.config.frames_per_read)
        if len(frames) and frames.timestamps_s[0] <= self._last_time:
            raise RuntimeError(
                f"BioTac source of {self.id!r} went back in time ({frames.timestamps_s[0]} after "
                f"{self._last_time}); a recording must have increasing timestamps"
            )
        if len(frames):
            self._last_time = float(frames.timestamps_s[-1])
        return frames

    def read(self) -> SampleBatch:
        return self.read_frames().to_sample_batch()

    def iter_recordings(self) -> Iterator[SampleBatch]:
        """Synthetic trials one at a time (other sources: the whole recording)."""
        if not isinstance(self._source, _SyntheticSource):
            yield from super().iter_recordings()
            return
        while not self._source.exhausted:
            frames = self._source.next_trial()
            if len(frames):
                self._last_time = float(frames.timestamps_s[-1])
                yield frames.to_sample_batch()

    def close(self) -> None:
        self._source.close()
