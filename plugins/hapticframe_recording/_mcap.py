"""The ``recording`` sensor: a sensor channel of a ``run.mcap`` fed into a pipeline again."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from hapticframe import UsageError
from hapticframe.kinds import BuildContext, ChannelInfo, SampleBatch, Sensor
from hapticframe.recording import find_recording, read_recording
from hapticframe.tare import tare_reference

from ._mcap_config import McapRecordingConfig

__all__ = ["RecordingSensor", "demo_messages", "recorded_samples", "tared_samples"]

#: The wall clock a paced sensor waits on (tests replace both).
_monotonic: Callable[[], float] = time.monotonic
_sleep: Callable[[float], None] = time.sleep


def recorded_samples(
    messages: list[tuple[int, dict[str, Any]]], source: str
) -> tuple[SampleBatch, dict[str, ChannelInfo], list[int]]:
    """Join a channel's ``hapticframe.SampleBatch`` messages: the samples, each channel's
    info (recorded unit and rate; a rate not recorded is one over the median period) and
    where each message ends (sample counts)."""
    times: list[np.ndarray] = []
    channels: dict[str, list[np.ndarray]] = {}
    valid: dict[str, list[np.ndarray]] = {}
    units: dict[str, str] = {}
    rates: dict[str, float] = {}
    ends: list[int] = []
    total = 0
    for _, data in messages:
        t = np.asarray(data.get("timestamps_s", []), dtype=np.float64).reshape(-1)
        n = len(t)
        if not n:
            continue
        recorded = data.get("channels") or {}
        if not channels:
            channels = {name: [] for name in recorded}
        if set(recorded) != set(channels):
            raise ValueError(f"{source}: a message holds channels {sorted(recorded)}, "
                             f"the first held {sorted(channels)}; the recording is damaged")
        for name, values in recorded.items():
            channels[name].append(np.asarray(values, dtype=np.float64).reshape(n, -1))
            flags = (data.get("valid") or {}).get(name)
            valid.setdefault(name, []).append(
                np.ones(n, dtype=bool) if flags is None else np.asarray(flags, dtype=bool))
        units.update(data.get("units") or {})
        rates.update(data.get("rates_hz") or {})
        times.append(t)
        total += n
        ends.append(total)
    if not total:
        raise ValueError(f"{source} holds no samples")
    timestamps = np.concatenate(times)
    period = np.diff(timestamps)
    period = period[period > 0]
    fallback = 1.0 / float(np.median(period)) if period.size else 1.0
    joined: dict[str, np.ndarray] = {}
    info: dict[str, ChannelInfo] = {}
    for name, parts in channels.items():
        shape = _sample_shape(messages, name)
        joined[name] = np.concatenate(parts).reshape(total, *shape)
        rate = rates.get(name)
        info[name] = ChannelInfo(shape, str(units.get(name, "1")),
                                 float(rate) if rate is not None and math.isfinite(rate)
                                 else fallback)
    flags = {name: np.concatenate(parts) for name, parts in valid.items()}
    flags = {name: mask for name, mask in flags.items() if not mask.all()}
    return SampleBatch(timestamps, joined, flags), info, ends


def tared_samples(samples: SampleBatch, n_frames: int,
                  channels: tuple[str, ...] | None = None, source: str = "") -> SampleBatch:
    """``samples`` with each of ``channels`` (None: all) minus its causal tare reference
    over the first ``n_frames`` samples (:mod:`hapticframe.tare`); invalid samples stay
    out of the reference. An unknown channel is a ValueError naming the recorded ones."""
    if n_frames <= 0:
        return samples
    names = tuple(samples.channels) if channels is None else channels
    unknown = [n for n in names if n not in samples.channels]
    if unknown:
        raise ValueError(f"{source}: tare_channels names {unknown[0]!r}; the recorded channels "
                         f"are {', '.join(sorted(samples.channels))}")
    out = dict(samples.channels)
    for name in names:
        values = np.asarray(samples.channels[name], dtype=np.float64)
        valid = samples.valid.get(name)
        out[name] = values - tare_reference(values, n_frames, valid)
    return SampleBatch(samples.timestamps_s, out, dict(samples.valid))


def demo_messages() -> list[tuple[int, dict[str, Any]]]:
    """Three recorded messages of ten samples of a 2-D force (N) at 100 Hz, one sample
    invalid, as a run records them."""
    out = []
    for k in range(3):
        t = (np.arange(10) + 10 * k) / 100.0
        force = np.column_stack([np.sin(2 * np.pi * t), 0.5 * np.cos(2 * np.pi * t)])
        valid = np.ones(10, dtype=bool)
        valid[3] = k != 1
        out.append((round(t[-1] * 1e9), {
            "timestamps_s": t.tolist(), "channels": {"force_n": force.tolist()},
            "valid": {"force_n": valid.tolist()}, "units": {"force_n": "N"},
            "rates_hz": {"force_n": 100.0}}))
    return out


def _sample_shape(messages: list[tuple[int, dict[str, Any]]], name: str) -> tuple[int, ...]:
    for _, data in messages:
        values = (data.get("channels") or {}).get(name)
        if values:
            return tuple(np.asarray(values, dtype=np.float64).shape[1:])
    return ()


class RecordingSensor(Sensor):
    """Replays one recorded sensor channel of a ``run.mcap`` with its recorded timestamps.

    A streaming read delivers the samples of the next recorded message (0.1 to 0.2 s of
    them, see docs/recording.md), paced in real time with ``pace: true``;
    :meth:`deliver_until` instead lets the reads deliver exactly up to a sample count
    (``hapticframe replay`` cuts the streams where the recorded run committed them). A
    missing file, channel or sample is a ``ValueError`` (exit status 2) naming the file and
    listing the recorded sensor channels.
    With ``tare_frames`` the channels are zeroed on the recording's first samples exactly as
    the biotac sensor's replay zeroes its frames (:func:`tared_samples`).

    Parameters
    ----------
    config : McapRecordingConfig
    context : BuildContext
        Needs no inputs.
    """

    def __init__(self, config: McapRecordingConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        topic = config.topic or f"/sensor/{context.id}"
        if config.file is None:
            path, messages = Path("the demo recording"), {topic: demo_messages()}
        else:
            try:
                path = find_recording(Path(config.file))
                messages = read_recording(path)
            except UsageError as exc:
                raise ValueError(str(exc)) from exc
        found = messages.get(topic)
        if not found:
            held = sorted(t for t in messages if t.startswith(("/sensor/", "/feature_extractor/")))
            raise ValueError(f"{path} has no recorded channel {topic!r}; it holds "
                             f"{', '.join(held) or 'no sensor channels'} (set 'topic')")
        self._samples, info, self._ends = recorded_samples(found, f"{path} {topic}")
        self._samples = tared_samples(self._samples, config.tare_frames, config.tare_channels,
                                      f"{path} {topic}")
        self._channels = MappingProxyType(info)
        self._path, self._topic = path, topic
        self._cursor = 0
        self._limit: int | None = None
        self._start_wall: float | None = None

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def samples(self) -> SampleBatch:
        """Every recorded sample."""
        return self._samples

    def __len__(self) -> int:
        return len(self._samples)

    @property
    def delivered(self) -> int:
        """Samples delivered so far."""
        return self._cursor

    @property
    def exhausted(self) -> bool:
        return self._cursor >= len(self._samples)

    def deliver_until(self, count: int | None) -> None:
        """Let reads deliver up to ``count`` samples in all (one read: all of them); None
        returns to one recorded message per read."""
        self._limit = None if count is None else min(int(count), len(self._samples))

    def read(self) -> SampleBatch:
        start = self._cursor
        if self._limit is not None:
            stop = max(self._limit, start)
        else:
            i = int(np.searchsorted(self._ends, start, side="right"))
            stop = self._ends[i] if i < len(self._ends) else len(self._samples)
        self._cursor = stop
        if self.config.pace and stop > start:
            self._wait_for(float(self._samples.timestamps_s[stop - 1]))
        return self._samples.select(slice(start, stop))

    def _wait_for(self, t_s: float) -> None:
        now = _monotonic()
        if self._start_wall is None:
            self._start_wall = now - (t_s - float(self._samples.timestamps_s[0]))
        due = self._start_wall + t_s - float(self._samples.timestamps_s[0])
        if due > now:
            _sleep(due - now)

    def read_all(self, max_reads: int = 1_000_000) -> SampleBatch:
        start, self._cursor = self._cursor, len(self._samples)
        return self._samples.select(slice(start, self._cursor))

    def reset(self) -> None:
        """Replay from the first sample again."""
        self._cursor = 0
        self._start_wall = None

    def checkpoint(self) -> int:
        return self._cursor

    def rewind(self, checkpoint: int) -> None:
        self._cursor = int(checkpoint)
