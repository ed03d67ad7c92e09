"""The newcomer's plugin of issue 34 (``--plugin-module lab_newcomer``).

``lab-fake-ft``: a fake 3-axis force sensor written from the plugin guide as it stood, five
samples per read at 100 Hz on a time counter of its own. In a search it ran five times
ahead of the robot (sensor time 343.6 s against the robot's 68.7 s) and the run still ended
``ok``. ``lab-fake-ft-clocked`` is the same sensor with the guide's fix: its sample times
come from the run's clock (``context.clock.due_times``), so each read delivers what is due.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
from pydantic import Field

from hapticframe import ChannelSpec, ClassifierSpec, PluginConfig, SensorSpec, hookimpl
from hapticframe.kinds import ChannelInfo, Classifier, ClassProbabilities, SampleBatch, Sensor


class FakeFtConfig(PluginConfig):
    rate_hz: float = Field(100.0, gt=0, le=10_000, description="Sample rate.")
    samples_per_read: int = Field(5, ge=1, le=1000, description="Samples per read().")
    noise_n: float = Field(0.1, ge=0, description="Force noise (N).")
    late_s: float = Field(0.0, ge=0, description="Clocked: samples stamped this much early "
                          "(a device on a clock that lags the robot's).")


class FakeFt(Sensor):
    """As written from the old guide: ``samples_per_read`` samples per read, its own time."""

    def __init__(self, config: FakeFtConfig, context: Any) -> None:
        super().__init__(config, context)
        self.t = 0.0

    @property
    def channels(self) -> dict[str, ChannelInfo]:
        return {"force_n": ChannelInfo(shape=(3,), unit="N", rate_hz=self.config.rate_hz)}

    def read(self) -> SampleBatch:
        n, dt = self.config.samples_per_read, 1.0 / self.config.rate_hz
        times = self.t + dt * np.arange(1, n + 1)
        self.t = float(times[-1])
        force = self.config.noise_n * self.context.rng.standard_normal((n, 3))
        return SampleBatch(times, {"force_n": force})


class FakeFtClocked(FakeFt):
    """The same sensor on the run's clock: the samples due since the last one."""

    def read(self) -> SampleBatch:
        times = self.context.clock.due_times(self.config.rate_hz, after_s=self.t)
        if times.size:
            self.t = float(times[-1])
        force = self.config.noise_n * self.context.rng.standard_normal((times.size, 3))
        return SampleBatch(times - self.config.late_s, {"force_n": force})


class PlanarConfig(PluginConfig):
    threshold_n: float = Field(5.0, gt=0, description="Contact above this in-plane force.")


class PlanarForceClassifier(Classifier):
    """Reads the in-plane force (x, y): contact when its x component exceeds a threshold."""

    classes = ("free", "contact")

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        return self.predict_proba(batch)

    def predict_proba(self, batch: SampleBatch) -> ClassProbabilities:
        x = batch.channels["force_n"][:, 0]
        p = np.clip(x / (2 * self.config.threshold_n), 0.0, 1.0)
        return ClassProbabilities(batch.timestamps_s, np.column_stack([1 - p, p]), self.classes)

    def fit(self, batches: Any, labels: Any) -> None:
        """Nothing to fit."""


@hookimpl
def hapticframe_classifiers() -> Iterator[ClassifierSpec]:
    yield ClassifierSpec(
        name="lab-planar", summary="Contact from the in-plane force's x component.",
        config=PlanarConfig, factory=f"{__name__}:PlanarForceClassifier",
        consumes={"force_n": ChannelSpec((2,), "N", "uses the x component of (x, y)")},
    )


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield SensorSpec(
        name="lab-fake-ft", summary="A fake 3-axis force sensor on its own time counter.",
        config=FakeFtConfig, factory=f"{__name__}:FakeFt", inputs=(),
    )
    yield SensorSpec(
        name="lab-fake-ft-clocked", summary="The fake 3-axis force sensor on the run's clock.",
        config=FakeFtConfig, factory=f"{__name__}:FakeFtClocked", inputs=(),
        produces={"force_n": ChannelSpec((3,), "N", "x, y, z in the sensor frame")},
    )
