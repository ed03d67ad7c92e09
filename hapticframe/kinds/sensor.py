"""Sensor interface: a source of timestamped samples.

A sensor delivers :class:`~hapticframe.kinds.SampleBatch` records. In streaming use the run
loop calls :meth:`Sensor.read` once per control period and gets the samples acquired since
the previous call (possibly none). In batch use, a finite source (a recording, a synthetic
trial) is drained with :meth:`Sensor.read_all`.

Contract
--------
- ``timestamps_s`` are float64 seconds and strictly increasing across successive reads.
- Every channel declared in :attr:`Sensor.channels` is present in every batch with shape
  ``(n, *info.shape)`` and float64 dtype, in the unit the :class:`ChannelInfo` states.
- A simulated sensor that needs the robot's state names that robot in ``inputs``.
- Time stamps keep step with the run's clock (``context.clock``, the robot's time): a
  software sensor stamps its samples with ``context.clock.due_times(rate_hz, after_s=last)``
  and delivers exactly those; a closed loop ends as no result when a stream lies further
  from the robot's time than its ``ChannelInfo.latency_s`` plus one control period and one
  sample (the kit's ``check_sensor_keeps_time``).
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Iterator, Mapping
from typing import ClassVar

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import ChannelInfo, SampleBatch, concatenate_batches

__all__ = ["Sensor"]


class Sensor(Component):
    """A source of timestamped samples (BioTac, a wrist force/torque sensor, a replay)."""

    kind: ClassVar[Kind] = Kind.SENSOR

    @property
    @abstractmethod
    def channels(self) -> Mapping[str, ChannelInfo]:
        """Channel name → shape of one sample, unit and rate."""

    @abstractmethod
    def read(self) -> SampleBatch:
        """Samples acquired since the previous call (streaming use)."""

    @property
    def exhausted(self) -> bool:
        """True when a finite source has delivered its last sample. Live sensors: never."""
        return False

    def read_all(self, max_reads: int = 1_000_000) -> SampleBatch:
        """Drain a finite source into one batch (batch use)."""
        batches = []
        for _ in range(max_reads):
            if self.exhausted:
                break
            batches.append(self.read())
        else:
            raise RuntimeError(f"sensor {self.id!r} was not exhausted after {max_reads} reads")
        if not batches:
            return SampleBatch.empty(self.channels)
        return concatenate_batches(batches)

    def iter_recordings(self) -> Iterator[SampleBatch]:
        """A finite source's recordings (trials), one batch each, for training.

        Default: the whole source as one recording. Sources that hold several trials
        override this so that models never learn across a trial boundary.
        """
        yield self.read_all()
