"""Sensor-model interface: a located measurement becomes map observations.

Contract
--------
- :meth:`SensorModel.observe` takes a :class:`LocatedMeasurement` (fingertip positions,
  headings, class probabilities) and returns :class:`Observations`: points in the map frame
  with occupancy targets in [0, 1].
- Observing rows one at a time and concatenating gives the same observations as observing
  them all at once (streaming equals batch) for a fixed state; state that changes between
  movements (a count of interactions, a shrinking depth) changes in
  :meth:`Component.on_movement_end`.
"""

from __future__ import annotations

from abc import abstractmethod
from typing import ClassVar

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._records import LocatedMeasurement, Observations

__all__ = ["SensorModel"]


class SensorModel(Component):
    """Spreads sparse tactile measurements over the map (failure-zone kernels...)."""

    kind: ClassVar[Kind] = Kind.SENSOR_MODEL

    @abstractmethod
    def observe(self, measurement: LocatedMeasurement) -> Observations:
        """Map observations implied by ``measurement``."""
