"""A lab-local plugin module used by the core's tests (loaded with ``--plugin-module labplugin``).

It is small but real: a finite sensor that replays a fingertip sweep over a buried disc, a
threshold classifier, a point sensor model and a cell-averaging map, so an open-loop
experiment runs end to end without any bundled plugin.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping

import numpy as np
from numpy.typing import NDArray
from pydantic import Field

from hapticframe import (
    ClassifierSpec,
    FeatureExtractorSpec,
    MapSpec,
    PluginConfig,
    SensorModelSpec,
    SensorSpec,
    hookimpl,
)
from hapticframe.kinds import (
    ChannelInfo,
    Classifier,
    ClassProbabilities,
    FeatureExtractor,
    LocatedMeasurement,
    Map,
    MapEstimate,
    Observations,
    Region,
    SampleBatch,
    Sensor,
    SensorModel,
)


class SweepConfig(PluginConfig):
    samples: int = Field(400, ge=1, description="Samples in the recording.")
    chunk: int = Field(25, ge=1, description="Samples per read.")
    noise_n: float = Field(0.2, ge=0, description="Force noise (N).")
    peak_n: float = Field(40.0, ge=0, description="Force added at the disc's centre (N).")


class SweepSensor(Sensor):
    """Replays a straight sweep at y = 0.25 m across a disc at x = 0.4 m (finite source)."""

    def __init__(self, config: SweepConfig, context):  # type: ignore[no-untyped-def]
        super().__init__(config, context)
        n = config.samples
        self._t = 0.01 * (1 + np.arange(n))
        x = np.linspace(0.05, 0.70, n)
        self._pos = np.column_stack([x, np.full(n, 0.25)])
        near = np.exp(-((x - 0.40) / 0.03) ** 2)
        force = 5.0 + config.peak_n * near + config.noise_n * context.rng.standard_normal(n)
        self._force = np.column_stack([force, np.zeros(n)])
        self._contact = (np.abs(x - 0.40) < 0.03).astype(float)
        self._next = 0

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return {"force_n": ChannelInfo((2,), "N", 100.0),
                "position_m": ChannelInfo((2,), "m", 100.0),
                "contact": ChannelInfo((), "1", 100.0)}

    @property
    def exhausted(self) -> bool:
        return self._next >= len(self._t)

    def read(self) -> SampleBatch:
        rows = slice(self._next, self._next + self.config.chunk)
        self._next = min(self._next + self.config.chunk, len(self._t))
        return SampleBatch(self._t[rows], {"force_n": self._force[rows],
                                           "position_m": self._pos[rows],
                                           "contact": self._contact[rows]})


class ScaleConfig(PluginConfig):
    factor: float = Field(1.0, description="Multiplies every force sample.")


class ScaleExtractor(FeatureExtractor):
    """Scales the force channel (stateless, so streaming trivially equals batch)."""

    @property
    def output_channels(self) -> Mapping[str, ChannelInfo]:
        return {"force_n": ChannelInfo((2,), "N", 100.0)}

    def update(self, batch: SampleBatch) -> SampleBatch:
        force = batch.channels["force_n"]
        if not np.all(np.isfinite(force)):
            raise ValueError("force samples must be finite")
        return SampleBatch(batch.timestamps_s, {"force_n": self.config.factor * force})


class ThresholdConfig(PluginConfig):
    threshold_n: float = Field(20.0, gt=0, description="Force magnitude meaning contact.")
    width_n: float = Field(2.0, gt=0, description="Softness of the decision (N).")


class ThresholdClassifier(Classifier):
    """Contact when the force magnitude exceeds a threshold (stateless; trainable and
    persistent: see hapticframe.kinds.Trainable and Persistent)."""

    def __init__(self, config: ThresholdConfig, context):  # type: ignore[no-untyped-def]
        super().__init__(config, context)
        self.threshold_n = config.threshold_n
        self._report: dict[str, float] = {}

    def training_report(self) -> dict[str, float]:
        return dict(self._report)

    def fit(self, batches, labels) -> None:  # type: ignore[no-untyped-def]
        force = np.concatenate([np.linalg.norm(b.channels["force_n"], axis=1) for b in batches])
        label = np.concatenate(labels)
        self.threshold_n = float((force[label == 1].mean() + force[label == 0].mean()) / 2)
        self._report = {"threshold_n": self.threshold_n}

    def save(self, directory) -> None:  # type: ignore[no-untyped-def]
        import json
        from pathlib import Path

        saved = json.dumps({"threshold_n": self.threshold_n})
        (Path(directory) / "threshold.json").write_text(saved)

    def load(self, directory) -> None:  # type: ignore[no-untyped-def]
        import json
        from pathlib import Path

        text = (Path(directory) / "threshold.json").read_text()
        self.threshold_n = float(json.loads(text)["threshold_n"])

    @property
    def classes(self) -> tuple[str, ...]:
        return ("free", "contact")

    def update(self, batch: SampleBatch) -> ClassProbabilities:
        force = np.linalg.norm(batch.channels["force_n"], axis=1)
        if np.any(~np.isfinite(force)):
            raise ValueError("force samples must be finite")
        from scipy.special import expit

        p = expit((force - self.threshold_n) / self.config.width_n)
        return ClassProbabilities(batch.timestamps_s, np.column_stack([1 - p, p]), self.classes)


class PointConfig(PluginConfig):
    pass


class PointSensorModel(SensorModel):
    """One observation at the fingertip: the contact probability."""

    def observe(self, measurement: LocatedMeasurement) -> Observations:
        contact = measurement.probabilities[:, -1]
        return Observations(measurement.positions_m, contact)


class CellConfig(PluginConfig):
    cell_m: float = Field(0.02, gt=0, description="Cell size.")


class CellMap(Map):
    """Mean target per cell; 0.5 where nothing was observed."""

    def __init__(self, config: CellConfig, context):  # type: ignore[no-untyped-def]
        super().__init__(config, context)
        self._region = Region(0.0, 0.75, 0.0, 0.5)
        self.reset()

    @property
    def region(self) -> Region:
        return self._region

    def reset(self) -> None:
        nx, ny = int(np.ceil(0.75 / self.config.cell_m)), int(np.ceil(0.5 / self.config.cell_m))
        self._sum = np.zeros((ny, nx))
        self._n = np.zeros((ny, nx))

    def _cells(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ix = np.floor(p[:, 0] / self.config.cell_m).astype(np.int64)
        iy = np.floor(p[:, 1] / self.config.cell_m).astype(np.int64)
        ok = (ix >= 0) & (iy >= 0) & (ix < self._sum.shape[1]) & (iy < self._sum.shape[0])
        return ix, iy, ok

    def update(self, observations: Observations) -> None:
        ix, iy, ok = self._cells(observations.points_m)
        np.add.at(self._sum, (iy[ok], ix[ok]), observations.targets[ok])
        np.add.at(self._n, (iy[ok], ix[ok]), 1.0)

    def _query(self, p: NDArray[np.float64]) -> MapEstimate:
        ix, iy, ok = self._cells(p)
        mean = np.full(len(p), 0.5)
        n = np.zeros(len(p))
        n[ok] = self._n[iy[ok], ix[ok]]
        seen = n > 0
        idx = np.flatnonzero(ok)[seen[ok]]
        mean[idx] = self._sum[iy[idx], ix[idx]] / n[idx]
        return MapEstimate(mean, np.sqrt(mean * (1 - mean) / (1 + n)))


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield SensorSpec("lab-sweep", "Replays a fingertip sweep over a disc.", SweepConfig,
                     f"{__name__}:SweepSensor", capabilities=frozenset({"finite"}))
    yield SensorSpec("lab-needs-driver", "A device whose driver is not installed.", SweepConfig,
                     f"{__name__}:SweepSensor", requires=("no_such_vendor_driver",),
                     install_hint="pip install lab-vendor-driver")


SESSIONS: list[tuple[str, str]] = []
#: The session objects the hooks received (the tests check they are public views).
SEEN_SESSIONS: list[object] = []


@hookimpl
def hapticframe_session_start(session) -> None:  # type: ignore[no-untyped-def]
    SEEN_SESSIONS.append(session)
    SESSIONS.append(("start", session.experiment.model.name))


@hookimpl
def hapticframe_session_finish(session, status) -> None:  # type: ignore[no-untyped-def]
    SESSIONS.append(("finish", status))


@hookimpl
def hapticframe_run_metadata(session) -> dict[str, str]:  # type: ignore[no-untyped-def]
    return {"lab_rig": "sandbox-2"}


@hookimpl
def hapticframe_feature_extractors() -> Iterator[FeatureExtractorSpec]:
    yield FeatureExtractorSpec("lab-scale", "Scales the force channel.", ScaleConfig,
                               f"{__name__}:ScaleExtractor", consumes={"force_n": (2,)})


@hookimpl
def hapticframe_classifiers() -> Iterator[ClassifierSpec]:
    yield ClassifierSpec("lab-threshold", "Force threshold contact classifier.", ThresholdConfig,
                         f"{__name__}:ThresholdClassifier", consumes={"force_n": (2,)})


@hookimpl
def hapticframe_sensor_models() -> Iterator[SensorModelSpec]:
    yield SensorModelSpec("lab-point", "Contact probability at the fingertip.", PointConfig,
                          f"{__name__}:PointSensorModel")


@hookimpl
def hapticframe_maps() -> Iterator[MapSpec]:
    yield MapSpec("lab-cells", "Mean target per cell.", CellConfig, f"{__name__}:CellMap",
                  capabilities=frozenset({"exact-update"}))
