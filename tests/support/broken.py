"""Deliberately broken plugins: each breaks one contract the conformance kit checks.

``BROKEN`` maps a spec to the check it must fail and a fragment of the expected message.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from hapticframe import (
    ClassifierSpec,
    FeatureExtractorSpec,
    MapSpec,
    PlannerSpec,
    PluginConfig,
    RobotSpec,
    SensorModelSpec,
    SensorSpec,
)
from hapticframe.kinds import (
    ChannelInfo,
    ClassProbabilities,
    ExploratoryMovement,
    MapEstimate,
    Observations,
    Planner,
    Region,
    Robot,
    RobotState,
    SampleBatch,
)

from .heavy_config import HeavyConfig
from .labplugin import (
    CellConfig,
    CellMap,
    PointConfig,
    PointSensorModel,
    ScaleConfig,
    ScaleExtractor,
    SweepConfig,
    SweepSensor,
    ThresholdClassifier,
    ThresholdConfig,
)

M = __name__


class NotAComponent:
    def __init__(self, config, context):  # type: ignore[no-untyped-def]
        pass


class InfiniteConfig(PluginConfig):
    limit_n: float = Field(math.inf, description="An infinite default cannot be written as JSON.")


class RestartingClockSensor(SweepSensor):
    def read(self) -> SampleBatch:
        batch = super().read()
        return SampleBatch(batch.timestamps_s - batch.timestamps_s[0] if len(batch) else batch.timestamps_s,
                           dict(batch.channels))


class WrongShapeSensor(SweepSensor):
    @property
    def channels(self):  # type: ignore[no-untyped-def]
        return {**super().channels, "force_n": ChannelInfo((3,), "N", 100.0)}


class UndeclaredFeature(ScaleExtractor):
    def update(self, batch: SampleBatch) -> SampleBatch:
        out = super().update(batch)
        return SampleBatch(out.timestamps_s, {**out.channels, "extra": out.channels["force_n"]})


class NanFeatures(ScaleExtractor):
    def update(self, batch: SampleBatch) -> SampleBatch:
        force = batch.channels["force_n"]
        scaled = force / np.where(force == 0, np.nan, 1.0)  # silently NaN for zero input
        return SampleBatch(batch.timestamps_s, {"force_n": scaled})


class ChunkNormalisedClassifier(ThresholdClassifier):
    def update(self, batch: SampleBatch) -> ClassProbabilities:
        force = batch.channels["force_n"]
        centred = force - force.mean(axis=0) if len(force) else force
        return super().update(SampleBatch(batch.timestamps_s, {"force_n": centred + 20.0}))


class NanProbabilityClassifier(ThresholdClassifier):
    def update(self, batch: SampleBatch) -> ClassProbabilities:
        force = np.linalg.norm(batch.channels["force_n"], axis=1)
        p = force / force.max() if len(force) else force
        return ClassProbabilities(batch.timestamps_s, np.column_stack([1 - p, p]), self.classes)


class UnseededClassifier(ThresholdClassifier):
    def update(self, batch: SampleBatch) -> ClassProbabilities:
        p = np.random.default_rng().uniform(0, 1, len(batch))
        return ClassProbabilities(batch.timestamps_s, np.column_stack([1 - p, p]), self.classes)


class OverconfidentSensorModel(PointSensorModel):
    def observe(self, measurement):  # type: ignore[no-untyped-def]
        return Observations(measurement.positions_m, 2.0 * np.ones(len(measurement)))


class EveryTenthCallSensorModel(PointSensorModel):
    calls = 0

    def observe(self, measurement):  # type: ignore[no-untyped-def]
        self.calls += 1
        if self.calls % 10:
            return Observations.empty()
        return super().observe(measurement)


class OverflowingSensorModel(PointSensorModel):
    def observe(self, measurement):  # type: ignore[no-untyped-def]
        with np.errstate(over="ignore", invalid="ignore"):
            scale = np.exp(measurement.positions_m) / np.exp(measurement.positions_m)
        return Observations(measurement.positions_m * scale, measurement.probabilities[:, -1])


class EmptyQueryMap(CellMap):
    def query(self, points_m):  # type: ignore[no-untyped-def]
        est = super().query(points_m)
        if len(est.mean) == 0:
            return MapEstimate([0.5], [0.5])
        return est


class ForgetfulMap(CellMap):
    def update(self, observations: Observations) -> None:
        self.reset()
        super().update(observations)


class MeanOfNothingMap(CellMap):
    _level = 1.0

    def update(self, observations: Observations) -> None:
        with np.errstate(invalid="ignore"):
            level = float(np.mean(observations.targets)) if len(observations) else math.nan
        super().update(Observations(observations.points_m, np.full(len(observations), level)))
        self._level = level

    def query(self, points_m):  # type: ignore[no-untyped-def]
        est = super().query(points_m)
        return MapEstimate(est.mean * (self._level / max(self._level, 1e-12)), est.std)


class EndlessConfig(PluginConfig):
    pass


class EndlessPlanner(Planner):
    max_movements = 20

    def propose(self) -> ExploratoryMovement:
        return ExploratoryMovement((0.1, 0.1), (0.6, 0.1))


class LineRobotConfig(PluginConfig):
    restart_clock: bool = False
    ignore_halt: bool = False
    rewind_keeps_progress: bool = False


class LineRobot(Robot):
    """Moves along the line at the commanded speed; optionally misbehaves."""

    def __init__(self, config, context):  # type: ignore[no-untyped-def]
        super().__init__(config, context)
        self._t = 0.0
        self._state = RobotState(0.0, np.zeros(2), 0.0)
        self._movement: ExploratoryMovement | None = None
        self._s = 0.0

    @property
    def control_rate_hz(self) -> float:
        return 100.0

    @property
    def state(self) -> RobotState:
        return self._state

    def begin(self, movement: ExploratoryMovement) -> None:
        self._movement, self._s = movement, 0.0
        if self.config.restart_clock:
            self._t = 0.0

    def step(self) -> RobotState | None:
        m = self._movement
        if m is None or self._s > m.length_m:
            self._movement = None
            return None
        frac = self._s / m.length_m if m.length_m else 1.0
        self._t += 0.01
        self._state = RobotState(self._t, m.start_m + frac * (m.end_m - m.start_m), m.heading_rad)
        self._s += m.speed_m_per_s * 0.01
        if m.length_m == 0:
            self._s = math.inf
        return self._state

    def halt(self, reason: str) -> None:
        if not self.config.ignore_halt:
            self._movement = None

    def checkpoint(self):  # type: ignore[no-untyped-def]
        return self._t, self._s, self._movement, self._state

    def rewind(self, checkpoint) -> None:  # type: ignore[no-untyped-def]
        t, s, self._movement, self._state = checkpoint
        self._t = t
        if not self.config.rewind_keeps_progress:  # the broken variant forgets the distance
            self._s = s


GOOD = [
    SensorSpec("lab-sweep", "ok", SweepConfig, "tests.support.labplugin:SweepSensor", capabilities=frozenset({"finite"})),
    FeatureExtractorSpec("lab-scale", "ok", ScaleConfig, "tests.support.labplugin:ScaleExtractor", consumes={"force_n": (2,)}),
    ClassifierSpec("lab-threshold", "ok", ThresholdConfig, "tests.support.labplugin:ThresholdClassifier", consumes={"force_n": (2,)}),
    SensorModelSpec("lab-point", "ok", PointConfig, "tests.support.labplugin:PointSensorModel"),
    MapSpec("lab-cells", "ok", CellConfig, "tests.support.labplugin:CellMap", capabilities=frozenset({"exact-update"})),
    RobotSpec("lab-line", "ok", LineRobotConfig, f"{M}:LineRobot"),
]

_FORCE = {"force_n": (2,)}

#: (spec, check that must fail, fragment of its message)
BROKEN = [
    (SensorSpec("not-a-component", "x", SweepConfig, f"{M}:NotAComponent"), "check_spec_record", "does not derive"),
    (SensorSpec("missing-factory", "x", SweepConfig, f"{M}:Nowhere"), "check_builds", "does not exist"),
    (SensorSpec("infinite-config", "x", InfiniteConfig, "tests.support.labplugin:SweepSensor"),
     "check_config_round_trip", "plain JSON"),
    (SensorSpec("heavy-config", "x", HeavyConfig, "tests.support.labplugin:SweepSensor", requires=("decimal",)),
     "check_lazy_import", "also imports decimal"),
    (SensorSpec("restarting-clock", "x", SweepConfig, f"{M}:RestartingClockSensor"), "check_sensor_contract", "go back"),
    (SensorSpec("wrong-shape", "x", SweepConfig, f"{M}:WrongShapeSensor"), "check_sensor_contract", "declared (3,)"),
    (FeatureExtractorSpec("undeclared-feature", "x", ScaleConfig, f"{M}:UndeclaredFeature", consumes=_FORCE),
     "check_stream_contract", "output_channels"),
    (FeatureExtractorSpec("nan-features", "x", ScaleConfig, f"{M}:NanFeatures", consumes=_FORCE),
     "check_numerical_extremes", "silent NaNs"),
    (ClassifierSpec("chunk-normalised", "x", ThresholdConfig, f"{M}:ChunkNormalisedClassifier", consumes=_FORCE),
     "check_streaming_matches_batch", "streaming and batch"),
    (ClassifierSpec("nan-probabilities", "x", ThresholdConfig, f"{M}:NanProbabilityClassifier", consumes=_FORCE),
     "check_numerical_extremes", "invalid output"),
    (ClassifierSpec("unseeded", "x", ThresholdConfig, f"{M}:UnseededClassifier", consumes=_FORCE),
     "check_deterministic", "context.rng"),
    (ClassifierSpec("no-consumes", "x", ThresholdConfig, "tests.support.labplugin:ThresholdClassifier"),
     "check_stream_contract", "declares no 'consumes'"),
    (SensorModelSpec("overconfident", "x", PointConfig, f"{M}:OverconfidentSensorModel"),
     "check_sensor_model_contract", "invalid output"),
    (SensorModelSpec("every-tenth", "x", PointConfig, f"{M}:EveryTenthCallSensorModel"),
     "check_sensor_model_streaming", "row-by-row"),
    (SensorModelSpec("overflowing", "x", PointConfig, f"{M}:OverflowingSensorModel"),
     "check_sensor_model_extremes", "1e6 m away"),
    (MapSpec("empty-query", "x", CellConfig, f"{M}:EmptyQueryMap"), "check_map_contract", "empty query"),
    (MapSpec("forgetful", "x", CellConfig, f"{M}:ForgetfulMap"), "check_map_streaming_matches_batch", "sequential updates"),
    (MapSpec("mean-of-nothing", "x", CellConfig, f"{M}:MeanOfNothingMap"), "check_map_extremes", "no observations"),
    (PlannerSpec("endless", "x", EndlessConfig, f"{M}:EndlessPlanner"), "check_planner_contract", "max_movements"),
    (RobotSpec("restarting-robot", "x", LineRobotConfig, f"{M}:LineRobot", check_config={"restart_clock": True}),
     "check_robot_contract", "keep increasing"),
    (RobotSpec("ignores-halt", "x", LineRobotConfig, f"{M}:LineRobot", check_config={"ignore_halt": True}),
     "check_robot_halt", "after halt()"),
    (RobotSpec("rewind-keeps-progress", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"rewind_keeps_progress": True}), "check_rewind", "after rewind()"),
]

__all__ = ["BROKEN", "GOOD", "Region"]
