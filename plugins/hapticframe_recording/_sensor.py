"""The ``trace-recording`` sensor: a finite replay of one sensor a previous run recorded."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from types import MappingProxyType

from hapticframe.kinds import BuildContext, ChannelInfo, SampleBatch, Sensor

from ._config import TraceRecordingConfig
from ._replay import Recording, demo_trace, load_labels, read_trace, recording_from_arrays

__all__ = ["TraceRecordingSensor"]


class TraceRecordingSensor(Sensor):
    """Replays the channels of one recorded sensor, ``samples_per_read`` samples per read.

    The file is read once, when the sensor is built; a missing or malformed file, sensor,
    channel or label array is a :class:`~hapticframe_recording.RecordingError` (a
    ``ValueError``: the run stops with exit status 2 and says which). Timestamps are the
    recorded ones. A sample whose values are not all finite (or that the trace records as
    invalid) is delivered marked invalid in ``batch.valid``.

    For training, :meth:`iter_recordings` yields one batch per exploratory movement of the
    recorded robot, so that no model learns across a movement's boundary.

    Parameters
    ----------
    config : TraceRecordingConfig
    context : BuildContext
        Needs no inputs.
    """

    def __init__(self, config: TraceRecordingConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        if config.path is not None:
            arrays, source = read_trace(config.path)
        else:
            arrays, source = demo_trace(), "the demo recording"
        labels = None if config.labels is None else load_labels(config.labels, config.labels_key)
        self._recording = recording_from_arrays(
            arrays,
            source=source,
            component=config.component,
            channels=config.channels,
            robot=config.robot,
            split_movements=config.split_movements,
            labels=labels,
            label_channel=config.label_channel,
            unlabelled=config.unlabelled,
            rate_hz=config.rate_hz,
        )
        self._channels = MappingProxyType(dict(self._recording.info))
        self._cursor = 0

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def recording(self) -> Recording:
        """Everything this sensor replays."""
        return self._recording

    @property
    def exhausted(self) -> bool:
        return self._cursor >= len(self._recording)

    def read(self) -> SampleBatch:
        """The next ``samples_per_read`` recorded samples (none once exhausted)."""
        start = self._cursor
        stop = min(start + self.config.samples_per_read, len(self._recording))
        self._cursor = stop
        return self._recording.batch(start, stop)

    def read_all(self, max_reads: int = 1_000_000) -> SampleBatch:
        """Every sample not read yet, as one batch."""
        start, self._cursor = self._cursor, len(self._recording)
        return self._recording.batch(start, self._cursor)

    def iter_recordings(self) -> Iterator[SampleBatch]:
        """The samples not read yet, one batch per recorded exploratory movement."""
        for start, stop in self._recording.trial_bounds():
            if stop <= self._cursor:
                continue
            first = max(start, self._cursor)
            self._cursor = stop
            yield self._recording.batch(first, stop)

    def reset(self) -> None:
        """Replay from the first sample again."""
        self._cursor = 0

    def checkpoint(self) -> int:
        """The read position (the recording itself never changes)."""
        return self._cursor

    def rewind(self, checkpoint: int) -> None:
        self._cursor = int(checkpoint)
