"""Every stream of a closed loop keeps step with the robot's time (issue 34 §1).

A sensor whose timestamps run ahead of the robot (a software sensor that makes five samples
per read at 100 Hz while the robot steps 10 ms per read) or fall behind it (a device on
another clock) feeds the classifiers, the stall check and the maps with times no movement
had: the search's figures are then no result. :class:`StepCheck` holds each batch a
streamed sensor delivers against the run's clock (the robot's latest state time) and
reports the first stream out of step; the run loop then halts the robot and ends
the run as no result (``run.json``: ``details.out_of_step``, exit 1, every file kept).

A stream is ahead when its latest sample lies beyond the clock's time at the read, behind
when even its latest sample was due before the stream's previous read (it runs late); a
stream that stops delivering is a stall (the safety monitor's ``force_stream_stalled``).
The tolerance of a stream is its declared latency (the largest ``ChannelInfo.latency_s``
of its channels) plus one control period plus one sample period of its slowest channel (a
10 Hz stream's latest sample may be 0.1 s old without being late).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from hapticframe.kinds import RunClock, SampleBatch, Sensor

__all__ = ["STREAM_OUT_OF_STEP", "StepCheck"]

#: The halt reason of a movement that a stream out of step with the robot ended.
STREAM_OUT_OF_STEP = "stream_out_of_step"


@dataclass(frozen=True)
class _Stream:
    sensor: str
    latency_s: float
    sample_period_s: float


class StepCheck:
    """Holds each streamed sensor's batches against the run's clock.

    Parameters
    ----------
    clock : RunClock
        The run's clock (following the robot's time).
    sensors : mapping of str to Sensor
        The streamed sensors by id.
    """

    def __init__(self, clock: RunClock, sensors: Mapping[str, Sensor]) -> None:
        self.clock = clock
        self._streams: dict[str, _Stream] = {}
        for sid, sensor in sensors.items():
            channels = sensor.channels.values()
            latency = max((float(getattr(c, "latency_s", 0.0)) for c in channels), default=0.0)
            rates = [float(c.rate_hz) for c in channels
                     if math.isfinite(c.rate_hz) and c.rate_hz > 0]
            period = 1.0 / min(rates) if rates else 0.0
            self._streams[sid] = _Stream(sid, latency, period)
        #: The first stream found out of step (``run.json`` details), None while all keep it.
        self.fault: dict[str, Any] | None = None
        #: The clock's time at each stream's previous read (a sample stamped before it,
        #: beyond the tolerance, arrived late: the stream runs behind).
        self._previous: dict[str, float] = {}

    def checkpoint(self) -> dict[str, float]:
        """The previous reads' times, taken with a look-ahead batch's snapshots."""
        return dict(self._previous)

    def rewind(self, checkpoint: Mapping[str, float]) -> None:
        """Back to a :meth:`checkpoint` (the batch is replayed one step at a time)."""
        self._previous = dict(checkpoint)

    def tolerance_s(self, sensor_id: str) -> float:
        """How far a stream's latest sample may lie from the clock's time."""
        stream = self._streams[sensor_id]
        return stream.latency_s + self.clock.period_s + stream.sample_period_s

    def check(self, sensor_id: str, batch: SampleBatch) -> None:
        """Note ``batch`` (just read from ``sensor_id``); sets :attr:`fault` on the first
        stream whose latest sample lies beyond its tolerance from the clock's time."""
        if self.fault is not None or sensor_id not in self._streams:
            return
        now = self.clock.now_s()
        previous = self._previous.get(sensor_id)
        self._previous[sensor_id] = now
        if not len(batch):
            return
        tolerance = self.tolerance_s(sensor_id)
        # Ahead: its latest sample lies beyond the clock's time now. Behind: even its
        # latest sample was due before the previous read. A device that delivers the
        # backlog of a dropout catches up in that batch and keeps step; a stream that only
        # stops is a stall, which the safety monitor watches, not a clock out of step.
        last = float(batch.timestamps_s[-1])
        if last - now > tolerance + 1e-9:
            offset, at = last - now, last
        elif previous is not None and previous - last > tolerance + 1e-9:
            offset, at, now = last - previous, last, previous
        else:
            return
        stream = self._streams[sensor_id]
        ahead = offset > 0
        last = at
        self.fault = {
            "reason": STREAM_OUT_OF_STEP,
            "stream": sensor_id,
            "sensor_time_s": last,
            "robot_time_s": now,
            "offset_s": offset,
            "tolerance_s": tolerance,
            "latency_s": stream.latency_s,
            "control_period_s": self.clock.period_s,
            "detail": (
                f"sensor {sensor_id!r} ran {'ahead of' if ahead else 'behind'} the robot: its "
                f"latest sample is stamped {last:.6g} s at robot time {now:.6g} s "
                f"({abs(offset):.4g} s {'ahead' if ahead else 'behind'}; allowed "
                f"{tolerance:.4g} s: latency {stream.latency_s:g} s + control period "
                f"{self.clock.period_s:g} s + one sample {stream.sample_period_s:g} s). "
                "Stamp its samples with the run's clock: "
                "context.clock.due_times(rate_hz, after_s=last_time) in a software sensor, "
                "or declare the stream's latency (ChannelInfo.latency_s) if it is a device's"
            ),
        }
