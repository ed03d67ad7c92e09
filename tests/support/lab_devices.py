"""A lab-local plugin module of hand-written devices and two-clock sensors
(``--plugin-module lab_devices``), for the core's tests of the device lifecycle and of
input alignment.

The devices implement :class:`hapticframe.kinds.Device` by hand (no
:class:`~hapticframe.devices.DeviceLifecycle`), so the run depends only on the protocol.
Every lifecycle call and every robot halt is logged in :data:`EVENTS`, in order.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any, Literal

import numpy as np
from pydantic import Field

from hapticframe import (
    FeatureExtractorSpec,
    PlannerSpec,
    PluginConfig,
    RobotSpec,
    SensorSpec,
    hookimpl,
)
from hapticframe.devices import DeviceError, DeviceHealth
from hapticframe.kinds import (
    ChannelInfo,
    ExploratoryMovement,
    FeatureExtractor,
    InputAlignment,
    Planner,
    Robot,
    RobotState,
    SampleBatch,
    Sensor,
)

#: (event, component id) for every configure, activate, deactivate, cleanup, close and
#: halt (``("halt", "arm:device failure")``), in call order.
EVENTS: list[tuple[str, str]] = []


class HandMadeDevice:
    """The Device protocol written out by hand: configure → activate → deactivate → cleanup."""

    id: str
    live: bool

    def _start_device(self, live: bool) -> None:
        self._state = "unconfigured"
        self._health = DeviceHealth()
        self.live = live

    @property
    def health(self) -> DeviceHealth:
        return self._health

    @property
    def active(self) -> bool:
        return self._state == "active"

    def configure(self) -> None:
        if self._state != "unconfigured":
            raise DeviceError(f"{self.id}: configure while {self._state}")
        EVENTS.append(("configure", self.id))
        self._state = "inactive"

    def activate(self) -> None:
        if self._state != "inactive":
            raise DeviceError(f"{self.id}: activate while {self._state}")
        EVENTS.append(("activate", self.id))
        self._state = "active"

    def deactivate(self) -> None:
        if self._state == "active":  # idempotent: a second call does nothing
            EVENTS.append(("deactivate", self.id))
            self._state = "inactive"

    def cleanup(self) -> None:
        if self._state == "inactive":
            EVENTS.append(("cleanup", self.id))
            self._state = "unconfigured"

    def close(self) -> None:
        EVENTS.append(("close", self.id))
        self.deactivate()
        self.cleanup()


class DeviceSensorConfig(PluginConfig):
    reads: int = Field(6, ge=1, description="Reads before the sensor is exhausted.")
    fail_at_read: int = Field(0, ge=0, description="The read that raises DeviceError (0: none).")
    crc_errors_per_read: int = Field(0, ge=0, description="CRC errors counted per read.")
    live: bool = Field(False, description="Whether it claims to be real hardware.")


class DeviceSensor(HandMadeDevice, Sensor):
    """One force sample per read; counts frames and (on request) CRC errors and resyncs."""

    def __init__(self, config: DeviceSensorConfig, context: Any) -> None:
        super().__init__(config, context)
        self._start_device(config.live)
        self._reads = 0
        robots = [c for c in context.inputs.values() if isinstance(c, Robot)]
        self._robot = robots[0] if robots else None

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return {"force_n": ChannelInfo((2,), "N", 100.0)}

    @property
    def exhausted(self) -> bool:
        return self._robot is None and self._reads >= self.config.reads

    def read(self) -> SampleBatch:
        if not self.active:
            raise RuntimeError(f"{self.id} was read while {self._state}")
        self._reads += 1
        if self._reads == self.config.fail_at_read:
            raise DeviceError(f"{self.id}: no valid frame for 0.16 s and 3 recoveries failed")
        self._health.frames += 1
        self._health.bytes += 16
        self._health.crc_errors += self.config.crc_errors_per_read
        self._health.resyncs += 4 * self.config.crc_errors_per_read
        t = self._robot.state.timestamp_s if self._robot is not None else 0.01 * self._reads
        return SampleBatch(np.array([t]), {"force_n": np.array([[1.0, 0.0]])})


class LineRobotConfig(PluginConfig):
    steps: int = Field(4, ge=1, description="Steps per movement.")


class LineRobot(HandMadeDevice, Robot):
    """Steps along a straight line; logs its halts."""

    def __init__(self, config: LineRobotConfig, context: Any) -> None:
        super().__init__(config, context)
        self._start_device(False)
        self._state_now = RobotState(0.0, np.zeros(2), 0.0)
        self._remaining = 0
        self._reason = ""

    @property
    def control_rate_hz(self) -> float:
        return 100.0

    @property
    def state(self) -> RobotState:
        return self._state_now

    @property
    def halt_reason(self) -> str:
        return self._reason

    def begin(self, movement: ExploratoryMovement) -> None:
        self._remaining = self.config.steps
        self._reason = ""

    def step(self) -> RobotState | None:
        if self._remaining <= 0:
            return None
        self._remaining -= 1
        previous = self._state_now
        self._state_now = RobotState(previous.timestamp_s + 0.01,
                                     previous.position_m + np.array([0.001, 0.0]), 0.0)
        return self._state_now

    def halt(self, reason: str) -> None:
        EVENTS.append(("halt", f"{self.id}:{reason}"))
        self._remaining = 0
        self._reason = reason


class LinePlannerConfig(PluginConfig):
    movements: int = Field(3, ge=1, description="Movements to propose.")


class LinePlanner(Planner):
    """Proposes the same short line a fixed number of times."""

    def __init__(self, config: LinePlannerConfig, context: Any) -> None:
        super().__init__(config, context)
        self._proposed = 0

    def propose(self) -> ExploratoryMovement | None:
        if self._proposed >= self.config.movements:
            return None
        self._proposed += 1
        return ExploratoryMovement(np.array([0.1, 0.2]), np.array([0.3, 0.2]), phase="line")


class ClockConfig(PluginConfig):
    channel: Literal["force_n", "accel_m_per_s2"] = Field("force_n", description="Its channel.")
    rate_hz: float = Field(100.0, gt=0, description="Sample rate.")
    phase_s: float = Field(0.0, ge=0, description="Time of the first sample.")
    duration_s: float = Field(1.0, gt=0, description="Length of the recording.")
    tick_s: float = Field(0.05, gt=0, description="Time each read covers.")


class ClockSensor(Sensor):
    """A finite recording on its own clock; each read delivers the samples of one tick."""

    def __init__(self, config: ClockConfig, context: Any) -> None:
        super().__init__(config, context)
        n = int(np.floor((config.duration_s - config.phase_s) * config.rate_hz)) + 1
        self._t = config.phase_s + np.arange(n) / config.rate_hz
        self._values = np.column_stack([np.sin(7.0 * self._t), np.cos(3.0 * self._t)])
        self._reads = 0

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        unit = "N" if self.config.channel == "force_n" else "m/s^2"
        return {self.config.channel: ChannelInfo((2,), unit, self.config.rate_hz)}

    @property
    def exhausted(self) -> bool:
        return self._reads * self.config.tick_s > self.config.duration_s

    def read(self) -> SampleBatch:
        low, high = self._reads * self.config.tick_s, (self._reads + 1) * self.config.tick_s
        self._reads += 1
        rows = (self._t > low) & (self._t <= high) if low > 0 else self._t <= high
        return SampleBatch(self._t[rows], {self.config.channel: self._values[rows]})


class MixConfig(PluginConfig):
    method: Literal["hold", "linear"] = Field("hold", description="How the inputs are aligned.")
    max_age_s: float = Field(0.05, gt=0, description="Oldest usable acceleration sample.")
    smoothing: float = Field(0.2, gt=0, le=1, description="Weight of a new sample.")
    forgetful: bool = Field(False, description="Forget the state at every update (a bug).")


class MixExtractor(FeatureExtractor):
    """Smoothed force plus acceleration from two inputs on different clocks; an invalid
    (stale) acceleration leaves the state as it was."""

    def __init__(self, config: MixConfig, context: Any) -> None:
        super().__init__(config, context)
        self._level = 0.0
        self._report: dict[str, int] = {}

    def fit(self, batches: Any) -> None:
        """Learns nothing; reports what the joined recordings held."""
        self._report = {
            "recordings": len(batches),
            "samples": sum(len(b) for b in batches),
            "valid_accel": sum(int(b.valid["accel_m_per_s2"].sum()) for b in batches),
        }

    def training_report(self) -> Mapping[str, int]:
        return dict(self._report)

    @property
    def input_alignment(self) -> InputAlignment:
        return InputAlignment(self.config.method, self.config.max_age_s)

    @property
    def output_channels(self) -> Mapping[str, ChannelInfo]:
        return {"mix": ChannelInfo((), "1", 100.0)}

    def reset(self) -> None:
        self._level = 0.0

    def update(self, batch: SampleBatch) -> SampleBatch:
        if self.config.forgetful:
            self.reset()
        force = batch.channels["force_n"][:, 0]
        accel = batch.channels["accel_m_per_s2"][:, 0]
        usable = np.isfinite(force) & np.isfinite(accel)
        if "accel_m_per_s2" in batch.valid:
            usable &= batch.valid["accel_m_per_s2"]
        out = np.empty(len(batch))
        weight = self.config.smoothing
        for i in range(len(batch)):
            if usable[i]:
                self._level += weight * (force[i] + accel[i] - self._level)
            out[i] = self._level
        return SampleBatch(batch.timestamps_s, {"mix": out})


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    # It ends after `reads` reads when no robot carries it (an open loop's source).
    yield SensorSpec("lab-device", "A hand-made device sensor.", DeviceSensorConfig,
                     f"{__name__}:DeviceSensor", capabilities=frozenset({"finite"}))
    yield SensorSpec("lab-clock", "A recording on its own clock.", ClockConfig,
                     f"{__name__}:ClockSensor", capabilities=frozenset({"finite"}))


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec("lab-line-robot", "A hand-made device robot.", LineRobotConfig,
                    f"{__name__}:LineRobot")


@hookimpl
def hapticframe_planners() -> Iterator[PlannerSpec]:
    yield PlannerSpec("lab-line-planner", "The same line, a few times.", LinePlannerConfig,
                      f"{__name__}:LinePlanner", inputs=())


@hookimpl
def hapticframe_feature_extractors() -> Iterator[FeatureExtractorSpec]:
    consumes = {"force_n": (2,), "accel_m_per_s2": (2,)}
    yield FeatureExtractorSpec("lab-mix", "Force plus acceleration from two clocks.", MixConfig,
                               f"{__name__}:MixExtractor", consumes=consumes)
    yield FeatureExtractorSpec("lab-mix-forgetful", "lab-mix that forgets its state.",
                               MixConfig, f"{__name__}:MixExtractor", consumes=consumes,
                               check_config={"forgetful": True})
