"""Deliberately broken plugins: each breaks one contract the conformance kit checks.

``BROKEN`` maps a spec to the check it must fail and a fragment of the expected message.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from pydantic import Field

from hapticframe import (
    ClassifierSpec,
    FeatureExtractorSpec,
    Knob,
    MapSpec,
    PlannerSpec,
    PluginConfig,
    RobotSpec,
    SensorModelSpec,
    SensorSpec,
    Size,
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
from .lab_devices import DeviceSensorConfig, MixConfig
from .lab_newcomer import FakeFtConfig
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


class BufferedSweepConfig(SweepConfig):
    buffer_samples: int = Field(100, ge=1, description="Samples of history kept (no upper "
                                "bound, and the validator below under-declares it).")


def understated_sizes(config: BufferedSweepConfig, context: object) -> Iterator[Size]:
    """Declares the buffer as a size, but says it costs nothing."""
    yield Size("buffer_samples", f"a history of {config.buffer_samples} samples")


class BufferedSweepSensor(SweepSensor):
    """Allocates its whole history up front: ``buffer_samples`` float64 of it."""

    def __init__(self, config: BufferedSweepConfig, context):  # type: ignore[no-untyped-def]
        super().__init__(config, context)
        self.history = np.zeros(config.buffer_samples)


class InfiniteConfig(PluginConfig):
    limit_n: float = Field(math.inf, description="An infinite default cannot be written as JSON.")


class RestartingClockSensor(SweepSensor):
    def read(self) -> SampleBatch:
        batch = super().read()
        times_s = batch.timestamps_s
        restarted_s = times_s - times_s[0] if len(batch) else times_s
        return SampleBatch(restarted_s, dict(batch.channels))


class WrongShapeSensor(SweepSensor):
    @property
    def channels(self):  # type: ignore[no-untyped-def]
        return {**super().channels, "force_n": ChannelInfo((3,), "N", 100.0)}


class NanDropoutSensor(SweepSensor):
    """Every seventh force sample is lost; ``flag_dropouts`` says how the loss is reported."""

    # None: no validity at all; False: marked valid; True: invalid.
    flag_dropouts: bool | None = None

    def read(self) -> SampleBatch:
        batch = super().read()
        force = np.array(batch.channels["force_n"])
        lost = np.round(batch.timestamps_s / 0.01).astype(int) % 7 == 0
        force[lost] = np.nan
        channels = {**batch.channels, "force_n": force}
        if self.flag_dropouts is None:
            return SampleBatch(batch.timestamps_s, channels)
        valid = ~lost if self.flag_dropouts else np.ones(len(batch), dtype=bool)
        return SampleBatch(batch.timestamps_s, channels, {"force_n": valid})


class UnflaggedNanSensor(NanDropoutSensor):
    flag_dropouts = None


class NanMarkedValidSensor(NanDropoutSensor):
    flag_dropouts = False


class FlaggedDropoutSensor(NanDropoutSensor):
    flag_dropouts = True


class UntaredReadAllSensor(SweepSensor):
    """read() refers the force to the first sample (a tare); read_all() forgets to."""

    def read(self) -> SampleBatch:
        batch = super().read()
        force = batch.channels["force_n"] - self._force[0]
        return SampleBatch(batch.timestamps_s, {**batch.channels, "force_n": force})

    def read_all(self, max_reads: int = 1_000_000) -> SampleBatch:
        self._next = len(self._t)
        return SampleBatch(self._t, {"force_n": self._force, "position_m": self._pos,
                                     "contact": self._contact})


class BoundaryDroppingSensor(SweepSensor):
    """Splits its recording into two trials and loses the sample at the boundary."""

    def iter_recordings(self) -> Iterator[SampleBatch]:
        whole = self.read_all()
        half = len(whole) // 2
        yield whole.select(slice(0, half))
        yield whole.select(slice(half + 1, None))


class LoopingReplaySensor(SweepSensor):
    """Declared finite, but replays its recording over and over on an increasing clock."""

    @property
    def exhausted(self) -> bool:
        return False

    def read(self) -> SampleBatch:
        if self._next >= len(self._t):
            self._t = self._t + (self._t[-1] - self._t[0] + 0.01)
            self._next = 0
        return super().read()


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


class UncheckedQueryMap(CellMap):
    def query(self, points_m):  # type: ignore[no-untyped-def]
        # Overrides the base's query and so skips its checks of the points.
        n = len(np.asarray(points_m, dtype=np.float64).reshape(-1, 2))
        return MapEstimate(np.full(n, 0.5), np.full(n, 0.5))


class ForgetfulMap(CellMap):
    def update(self, observations: Observations) -> None:
        self.reset()
        super().update(observations)


class InvertedMap(CellMap):
    def query(self, points_m):  # type: ignore[no-untyped-def]
        est = super().query(points_m)
        return MapEstimate(1.0 - np.asarray(est.mean), est.std)


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


class LinePlannerConfig(PluginConfig):
    spacing_m: float = 0.1
    max_lines: int = 12


class ZeroDepthPlannerConfig(LinePlannerConfig):
    """A commanded depth that may be 0, which every robot refuses at run time."""

    depth_m: float | None = Field(None, ge=0, le=0.3)


class InsetLinesPlanner(Planner):
    """Horizontal lines, each inset half a spacing from the left and right edges.

    On a region narrower than one spacing the inset lines start beyond its right edge.
    """

    def __init__(self, config, context):  # type: ignore[no-untyped-def]
        super().__init__(config, context)
        self.region = next(iter(context.inputs.values())).region
        self.max_movements = config.max_lines
        self._done = 0

    def _line(self, y: float) -> ExploratoryMovement:
        r, inset = self.region, self.config.spacing_m / 2
        return ExploratoryMovement((r.x_min_m + inset, y), (r.x_max_m - inset, y))

    def propose(self) -> ExploratoryMovement | None:
        r = self.region
        lines = max(1, int((r.y_max_m - r.y_min_m) / self.config.spacing_m))
        if self._done >= min(lines, self.max_movements):
            return None
        self._done += 1
        return self._line(r.y_min_m + (self._done - 0.5) * (r.y_max_m - r.y_min_m) / lines)


class FreeSpaceCentroidPlanner(InsetLinesPlanner):
    """After a first line, aims one line through the centroid of the map's free space.

    On a map occupied everywhere the centroid is 0 / 0: a NaN line.
    """

    def propose(self) -> ExploratoryMovement | None:
        if self._done >= 2:
            return None
        self._done += 1
        r = self.region
        y = float(r.center_m[1])
        if self._done == 2:
            the_map = next(iter(self.context.inputs.values()))
            ys = np.linspace(r.y_min_m, r.y_max_m, 11)
            free = 1.0 - the_map.query(np.column_stack([np.full(11, r.center_m[0]), ys])).mean
            with np.errstate(invalid="ignore", divide="ignore"):
                y = float(np.sum(free * ys) / np.sum(free))
        return ExploratoryMovement((r.x_min_m, y), (r.x_max_m, y))


class UntilSurePlanner(InsetLinesPlanner):
    """Rakes the middle line again until the map is sure somewhere (a std below 0.3).

    A map that stays unknown everywhere never becomes sure: it proposes forever.
    """

    def propose(self) -> ExploratoryMovement | None:
        the_map = next(iter(self.context.inputs.values()))
        if self._done and np.min(the_map.query(np.array([self.region.center_m])).std) < 0.3:
            return None
        self._done += 1
        r = self.region
        return ExploratoryMovement((r.x_min_m, r.center_m[1]), (r.x_max_m, r.center_m[1]))


class LineRobotConfig(PluginConfig):
    restart_clock: bool = False
    ignore_halt: bool = False
    rewind_keeps_progress: bool = False
    nan_on_zero_length: bool = False
    wait_at_workspace_edge: bool = False
    halt_only_when_moving: bool = False
    declare_workspace: bool = False
    enforce_workspace: bool = True
    refuse_bad_depth: bool = True


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

    @property
    def workspace(self) -> Region | None:
        """The kit scene's region, when ``declare_workspace`` is set."""
        if not self.config.declare_workspace:
            return None
        return self.context.scene.region.to_region()

    def begin(self, movement: ExploratoryMovement) -> None:
        # Overrides Robot.begin, so it checks what the base would (the broken variants skip).
        depth = movement.depth_m
        if self.config.refuse_bad_depth and depth is not None and not (
                math.isfinite(depth) and depth > 0):
            raise ValueError(f"robot {self.id!r}: movement depth must be positive, got {depth}")
        region = self.workspace
        if region is not None and self.config.enforce_workspace:  # the broken variant does not
            if not region.contains(np.vstack([movement.start_m, movement.end_m])).all():
                raise ValueError(f"robot {self.id!r}: the movement leaves the workspace")
        self._movement, self._s = movement, 0.0
        if self.config.restart_clock:
            self._t = 0.0

    def step(self) -> RobotState | None:
        m = self._movement
        if m is None or self._s > m.length_m:
            self._movement = None
            return None
        if self.config.nan_on_zero_length:  # the broken variant divides 0 by 0
            with np.errstate(invalid="ignore"):
                frac = np.float64(self._s) / m.length_m
        else:
            frac = self._s / m.length_m if m.length_m else 1.0
        self._t += 0.01
        position = m.start_m + frac * (m.end_m - m.start_m)
        if self.config.wait_at_workspace_edge:  # the broken variant holds at the edge,
            r = self.context.scene.region  # waiting for a target it cannot reach
            clamped = np.clip(position, (r.x_min_m, r.y_min_m), (r.x_max_m, r.y_max_m))
            if not np.array_equal(clamped, position):
                self._state = RobotState(self._t, clamped, m.heading_rad)
                return self._state
        self._state = RobotState(self._t, position, m.heading_rad)
        self._s += m.speed_m_per_s * 0.01
        if m.length_m == 0:
            self._s = math.inf
        return self._state

    def halt(self, reason: str) -> None:
        if self.config.halt_only_when_moving and self._s == 0.0:
            return  # the broken variant loses a halt that comes before the first step
        if not self.config.ignore_halt:
            self._movement = None

    def checkpoint(self):  # type: ignore[no-untyped-def]
        return self._t, self._s, self._movement, self._state

    def rewind(self, checkpoint) -> None:  # type: ignore[no-untyped-def]
        t, s, self._movement, self._state = checkpoint
        self._t = t
        if not self.config.rewind_keeps_progress:  # the broken variant forgets the distance
            self._s = s


D = "tests.support.lab_devices"
_TWO_CLOCKS = {"force_n": (2,), "accel_m_per_s2": (2,)}

GOOD = [
    SensorSpec("lab-sweep", "ok", SweepConfig, "tests.support.labplugin:SweepSensor",
               capabilities=frozenset({"finite"})),
    FeatureExtractorSpec("lab-scale", "ok", ScaleConfig, "tests.support.labplugin:ScaleExtractor",
                         consumes={"force_n": (2,)}),
    ClassifierSpec("lab-threshold", "ok", ThresholdConfig,
                   "tests.support.labplugin:ThresholdClassifier", consumes={"force_n": (2,)}),
    SensorModelSpec("lab-point", "ok", PointConfig, "tests.support.labplugin:PointSensorModel"),
    MapSpec("lab-cells", "ok", CellConfig, "tests.support.labplugin:CellMap",
            capabilities=frozenset({"exact-update"}),
            knobs=(Knob("cell_m", "smaller cells: finer map, more cells", values=(0.01, 0.02)),)),
    RobotSpec("lab-line", "ok", LineRobotConfig, f"{M}:LineRobot"),
    RobotSpec("lab-line-workspace", "ok", LineRobotConfig, f"{M}:LineRobot",
              check_config={"declare_workspace": True}),
    # NaN in samples the batch marks invalid is how a sensor reports a loss: accepted.
    SensorSpec("lab-flagged-dropouts", "ok", SweepConfig, f"{M}:FlaggedDropoutSensor",
               capabilities=frozenset({"finite"})),
    PlannerSpec("lab-inset-lines", "ok", LinePlannerConfig, f"{M}:InsetLinesPlanner",
                check_config={"spacing_m": 0.005}),
    # A device that can be read only while active: the kit brings it up and down.
    SensorSpec("lab-device", "ok", DeviceSensorConfig, f"{D}:DeviceSensor",
               capabilities=frozenset({"finite"}), check_config={"crc_errors_per_read": 1}),
    # Two inputs on different clocks, held or interpolated.
    FeatureExtractorSpec("lab-mix", "ok", MixConfig, f"{D}:MixExtractor", consumes=_TWO_CLOCKS),
    FeatureExtractorSpec("lab-mix-linear", "ok", MixConfig, f"{D}:MixExtractor",
                         consumes=_TWO_CLOCKS, check_config={"method": "linear"}),
]

_FORCE = {"force_n": (2,)}
_FINITE = frozenset({"finite"})

#: (spec, check that must fail, fragment of its message)
BROKEN = [
    (SensorSpec("not-a-component", "x", SweepConfig, f"{M}:NotAComponent"),
     "check_spec_record", "does not derive"),
    (SensorSpec("missing-factory", "x", SweepConfig, f"{M}:Nowhere"),
     "check_builds", "does not exist"),
    (SensorSpec("infinite-config", "x", InfiniteConfig, "tests.support.labplugin:SweepSensor"),
     "check_config_round_trip", "plain JSON"),
    (SensorSpec("heavy-config", "x", HeavyConfig, "tests.support.labplugin:SweepSensor",
                requires=("decimal",)),
     "check_lazy_import", "also imports decimal"),
    (SensorSpec("restarting-clock", "x", SweepConfig, f"{M}:RestartingClockSensor"),
     "check_sensor_contract", "go back"),
    (SensorSpec("wrong-shape", "x", SweepConfig, f"{M}:WrongShapeSensor"),
     "check_sensor_contract", "declared (3,)"),
    # Issue 34's newcomer: five samples a read at 100 Hz on a time counter of its own.
    (SensorSpec("own-time-counter", "x", FakeFtConfig, "tests.support.lab_newcomer:FakeFt"),
     "check_sensor_keeps_time", "context.clock.due_times"),
    (FeatureExtractorSpec("undeclared-feature", "x", ScaleConfig, f"{M}:UndeclaredFeature",
                          consumes=_FORCE),
     "check_stream_contract", "output_channels"),
    (FeatureExtractorSpec("nan-features", "x", ScaleConfig, f"{M}:NanFeatures", consumes=_FORCE),
     "check_numerical_extremes", "silent NaNs"),
    (ClassifierSpec("chunk-normalised", "x", ThresholdConfig, f"{M}:ChunkNormalisedClassifier",
                    consumes=_FORCE),
     "check_streaming_matches_batch", "streaming and batch"),
    (ClassifierSpec("nan-probabilities", "x", ThresholdConfig, f"{M}:NanProbabilityClassifier",
                    consumes=_FORCE),
     "check_numerical_extremes", "invalid output"),
    (ClassifierSpec("unseeded", "x", ThresholdConfig, f"{M}:UnseededClassifier", consumes=_FORCE),
     "check_deterministic", "context.rng"),
    (ClassifierSpec("no-consumes", "x", ThresholdConfig,
                    "tests.support.labplugin:ThresholdClassifier"),
     "check_stream_contract", "declares no 'consumes'"),
    (SensorModelSpec("overconfident", "x", PointConfig, f"{M}:OverconfidentSensorModel"),
     "check_sensor_model_contract", "invalid output"),
    (SensorModelSpec("every-tenth", "x", PointConfig, f"{M}:EveryTenthCallSensorModel"),
     "check_sensor_model_streaming", "row-by-row"),
    (SensorModelSpec("overflowing", "x", PointConfig, f"{M}:OverflowingSensorModel"),
     "check_sensor_model_extremes", "1e6 m away"),
    (MapSpec("misnamed-knob", "x", CellConfig, "tests.support.labplugin:CellMap",
             knobs=(Knob("cell_size_m", "smaller cells", values=(0.01, 0.02)),)),
     "check_knobs", "has no field 'cell_size_m'; did you mean 'cell_m'?"),
    (MapSpec("empty-query", "x", CellConfig, f"{M}:EmptyQueryMap"),
     "check_map_contract", "empty query"),
    (MapSpec("unchecked-query", "x", CellConfig, f"{M}:UncheckedQueryMap"),
     "check_map_refuses_bad_query_points", "a NaN query point"),
    (MapSpec("forgetful", "x", CellConfig, f"{M}:ForgetfulMap"),
     "check_map_streaming_matches_batch", "sequential updates"),
    (MapSpec("mean-of-nothing", "x", CellConfig, f"{M}:MeanOfNothingMap"),
     "check_map_extremes", "no observations"),
    (MapSpec("inverted", "x", CellConfig, f"{M}:InvertedMap"),
     "check_map_ranks_scattered_points", "inverted"),
    (PlannerSpec("endless", "x", EndlessConfig, f"{M}:EndlessPlanner"),
     "check_planner_contract", "max_movements"),
    (RobotSpec("restarting-robot", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"restart_clock": True}),
     "check_robot_contract", "keep increasing"),
    (RobotSpec("ignores-halt", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"ignore_halt": True}),
     "check_robot_halt", "after halt()"),
    (RobotSpec("halt-lost-before-first-step", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"halt_only_when_moving": True}),
     "check_robot_stops_at_once", "right after begin()"),
    (RobotSpec("moves-outside-workspace", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"declare_workspace": True, "enforce_workspace": False}),
     "check_robot_refuses_outside_workspace",
     "begin() accepted a movement that ends outside the workspace"),
    (RobotSpec("accepts-any-depth", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"refuse_bad_depth": False}),
     "check_robot_refuses_bad_depth", "begin() accepted a negative depth"),
    (RobotSpec("rewind-keeps-progress", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"rewind_keeps_progress": True}), "check_rewind", "after rewind()"),
    (SensorSpec("unflagged-nan", "x", SweepConfig, f"{M}:UnflaggedNanSensor", capabilities=_FINITE),
     "check_sensor_valid_samples_finite", "NaN or infinity in channel 'force_n' at t = 0.07 s"),
    (SensorSpec("nan-marked-valid", "x", SweepConfig, f"{M}:NanMarkedValidSensor",
                capabilities=_FINITE),
     "check_sensor_valid_samples_finite", "which the batch marks valid"),
    (SensorSpec("untared-read-all", "x", SweepConfig, f"{M}:UntaredReadAllSensor",
                capabilities=_FINITE),
     "check_sensor_read_all_matches_reads", "read_all() and successive read()s"),
    (SensorSpec("boundary-dropping", "x", SweepConfig, f"{M}:BoundaryDroppingSensor",
                capabilities=_FINITE),
     "check_sensor_read_all_matches_reads",
     "iter_recordings(), joined, and read_all() differ: 399 samples against 400"),
    (SensorSpec("looping-replay", "x", SweepConfig, f"{M}:LoopingReplaySensor",
                capabilities=_FINITE),
     "check_sensor_contract", "was not exhausted"),
    (SensorSpec("understated-size", "x", BufferedSweepConfig, f"{M}:BufferedSweepSensor",
                capabilities=_FINITE, validator=f"{M}:understated_sizes"),
     "check_declared_sizes", "buffer_samples = 4611686018427387904 is accepted by validate"),
    (PlannerSpec("inset-lines", "x", LinePlannerConfig, f"{M}:InsetLinesPlanner"),
     "check_planner_extremes", "smaller than one line spacing): movement"),
    (PlannerSpec("zero-depth", "x", ZeroDepthPlannerConfig, f"{M}:InsetLinesPlanner"),
     "check_run_range_ends", "depth_m = 0 is accepted; robots refuse"),
    (PlannerSpec("free-space-centroid", "x", LinePlannerConfig, f"{M}:FreeSpaceCentroidPlanner"),
     "check_planner_extremes", "invalid output on an all-occupied map"),
    (PlannerSpec("until-sure", "x", LinePlannerConfig, f"{M}:UntilSurePlanner"),
     "check_planner_extremes", "on an all-unknown map (0.5 everywhere): the planner proposed more"),
    (RobotSpec("nan-on-zero-length", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"nan_on_zero_length": True}),
     "check_robot_extremes", "zero-length movement gave states with NaN"),
    (RobotSpec("waits-at-workspace-edge", "x", LineRobotConfig, f"{M}:LineRobot",
               check_config={"wait_at_workspace_edge": True}), "check_robot_extremes",
     "a movement that leaves the workspace did not end within"),
    (FeatureExtractorSpec("forgets-between-ticks", "x", MixConfig, f"{D}:MixExtractor",
                          consumes=_TWO_CLOCKS, check_config={"forgetful": True}),
     "check_aligned_inputs_stream_as_batch", "inputs aligned tick by tick must equal"),
]

__all__ = ["BROKEN", "GOOD", "Region"]
