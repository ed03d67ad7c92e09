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
- A sensor model learned from calibration recordings is a :class:`TrainableSensorModel`:
  its :meth:`~TrainableSensorModel.fit` takes the recordings
  (:func:`hapticframe.read_calibration_run` reads one from a run's folder) and
  :meth:`~TrainableSensorModel.save` writes its fitted parameters (plain JSON or arrays,
  loaded without running code). ``hapticframe train`` fits every such sensor model on the
  runs of ``run.calibration_runs`` (``train --calibration DIR``) and saves it into
  ``DIR/<id>/``.
"""

from __future__ import annotations

from abc import abstractmethod
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, ClassVar, Protocol, runtime_checkable

from hapticframe._kind import Kind
from hapticframe.kinds._base import Component
from hapticframe.kinds._calibration import CalibrationRecording
from hapticframe.kinds._records import LocatedMeasurement, Observations

__all__ = ["CalibrationRecording", "SensorModel", "TrainableSensorModel"]


class SensorModel(Component):
    """Spreads sparse tactile measurements over the map (failure-zone kernels...)."""

    kind: ClassVar[Kind] = Kind.SENSOR_MODEL

    @abstractmethod
    def observe(self, measurement: LocatedMeasurement) -> Observations:
        """Map observations implied by ``measurement``."""


@runtime_checkable
class TrainableSensorModel(Protocol):
    """A sensor model whose parameters are learned from calibration recordings.

    A trainer calls :meth:`fit` once with every calibration recording, then :meth:`save`
    into a folder; a built model reads that folder with :meth:`load` (the failure-zone
    kernel: its ``model_dir`` setting). ``hapticframe train`` is that trainer
    (``run.calibration_runs``).
    """

    def fit(self, recordings: Sequence[CalibrationRecording]) -> None:
        """Learn the model's parameters from calibration recordings.

        Parameters
        ----------
        recordings : sequence of CalibrationRecording
            Each with the plate's poses along its movements, the classifier's class
            probabilities per sample (with timestamps) and the known buried objects.

        Raises
        ------
        ValueError
            When the recordings cannot determine the parameters (say, no movement
            interacted); the message says what is missing.
        """

    def training_report(self) -> Mapping[str, Any]:
        """What the last fit learned, as plain JSON-able values (empty before a fit)."""
        ...

    def save(self, directory: str | Path) -> Any:
        """Write the fitted parameters into ``directory`` (JSON or ``.npy``; no pickles)."""

    def load(self, directory: str | Path) -> None:
        """Read parameters :meth:`save` wrote; ``ValueError`` when they do not fit."""
