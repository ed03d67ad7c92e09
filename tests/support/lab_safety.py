"""A lab-local plugin module for the run's safety behaviour (``--plugin-module lab_safety``).

- ``lab-arm``: a robot that is a device (:class:`~hapticframe.devices.DeviceLifecycle`),
  stepping along each movement at 100 Hz on a global step clock (``t = k / 100``), with an
  optional workspace; it logs halts and torque-off in :data:`EVENTS`.
- ``lab-scripted-force``: a force sensor on the arm's step clock whose script is known: the
  force magnitude is ``force_n`` until ``cross_at_s`` and ``peak_n`` from then on; each read
  delivers the samples up to ``delay_steps`` steps before the arm's latest state (a sensor
  whose samples arrive late); from ``silent_from_s`` on its samples are invalid (or missing);
  ``sigterm_at_read`` sends the process SIGTERM from inside a read; ``stuck_at_read``
  blocks that read until the arm is halted (at most ``stuck_for_s`` seconds) and notes
  in :data:`STUCK` whether a halt freed it. With ``live: true`` the arm is a live device.
- ``lab-lines``: proposes the configured straight lines, one per movement, and records the
  results it is told about.

Both the arm and the sensor rewind (look-ahead runs use them).
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Iterator, Mapping
from typing import Any, Literal

import numpy as np
from pydantic import Field

from hapticframe import PlannerSpec, PluginConfig, RegionConfig, RobotSpec, SensorSpec, hookimpl
from hapticframe.devices import DeviceLifecycle
from hapticframe.kinds import (
    ChannelInfo,
    ExploratoryMovement,
    MovementResult,
    Planner,
    Region,
    Robot,
    RobotState,
    SampleBatch,
    Sensor,
)

#: (event, detail) in call order: ``("halt", "arm:force_limit")``, ``("torque_off", "arm")``,
#: ``("close", "wrist")``, ...
EVENTS: list[tuple[str, str]] = []
#: The movement results the planner was told about (``on_movement_end``).
RESULTS: list[MovementResult] = []

DT = 0.01
#: Set when the arm is halted (a stuck read waits for it).
HALTED = threading.Event()
#: For each stuck read: whether a halt freed it (False: it timed out).
STUCK: list[bool] = []


class ArmConfig(PluginConfig):
    workspace: RegionConfig | None = Field(None, description="Where the arm may go.")
    live: bool = Field(False, description="A live device (the run is paced, watched).")


class LabArm(DeviceLifecycle, Robot):
    """Moves the fingertip along each movement at its speed, one 10 ms step at a time."""

    def __init__(self, config: ArmConfig, context: Any) -> None:
        super().__init__(config, context)
        self.live = config.live
        self._k = 0  # global step count: the clock
        self._state = RobotState(0.0, np.zeros(2), 0.0)
        self._movement: ExploratoryMovement | None = None
        self._travelled = 0.0
        self._reason = ""

    @property
    def control_rate_hz(self) -> float:
        return 1.0 / DT

    @property
    def state(self) -> RobotState:
        return self._state

    @property
    def halt_reason(self) -> str:
        return self._reason

    @property
    def workspace(self) -> Region | None:
        ws = self.config.workspace
        return None if ws is None else ws.to_region()

    def on_deactivate(self) -> None:
        EVENTS.append(("torque_off", self.id))

    def begin(self, movement: ExploratoryMovement) -> None:
        region = self.workspace
        if region is not None and not region.contains(
                np.vstack([movement.start_m, movement.end_m])).all():
            raise ValueError(f"robot {self.id!r}: the movement leaves the workspace")
        self._movement, self._travelled, self._reason = movement, 0.0, ""
        self._state = RobotState(self._k * DT, movement.start_m, movement.heading_rad)

    def step(self) -> RobotState | None:
        m = self._movement
        if m is None:
            return None
        self._k += 1
        self._travelled = min(self._travelled + m.speed_m_per_s * DT, m.length_m)
        frac = self._travelled / m.length_m if m.length_m else 1.0
        self._state = RobotState(self._k * DT, m.start_m + frac * (m.end_m - m.start_m),
                                 m.heading_rad)
        if self._travelled >= m.length_m:
            self._movement = None
        return self._state

    def halt(self, reason: str) -> None:
        EVENTS.append(("halt", f"{self.id}:{reason}"))
        HALTED.set()
        if self._movement is not None:
            self._movement = None
            self._reason = reason

    def checkpoint(self) -> tuple[int, RobotState, ExploratoryMovement | None, float, str]:
        return self._k, self._state, self._movement, self._travelled, self._reason

    def rewind(self, checkpoint: tuple[int, RobotState, ExploratoryMovement | None, float, str]
               ) -> None:
        self._k, self._state, self._movement, self._travelled, self._reason = checkpoint

    def close(self) -> None:
        EVENTS.append(("close", self.id))
        super().close()


class ScriptedForceConfig(PluginConfig):
    force_n: float = Field(10.0, ge=0, description="Force magnitude before cross_at_s.")
    peak_n: float = Field(100.0, ge=0, description="Force magnitude from cross_at_s on.")
    cross_at_s: float = Field(1e9, description="Time of the first sample at peak_n.")
    delay_steps: int = Field(0, ge=0, description="Steps each sample arrives late.")
    silent_from_s: float = Field(1e9, description="Samples after this are not valid.")
    silent_as: Literal["invalid", "missing"] = Field("invalid", description="How.")
    sigterm_at_read: int = Field(0, ge=0, description="Read that sends SIGTERM (0: none).")
    stuck_at_read: int = Field(0, ge=0, description="Read that blocks until a halt (0: none).")
    stuck_for_s: float = Field(10.0, gt=0, description="At most this long (wall time).")


class ScriptedForceSensor(Sensor):
    """One sample per arm step, delivered ``delay_steps`` late, on the arm's clock."""

    def __init__(self, config: ScriptedForceConfig, context: Any) -> None:
        super().__init__(config, context)
        robots = [c for c in context.inputs.values() if isinstance(c, Robot)]
        if len(robots) != 1:
            raise ValueError("lab-scripted-force needs the arm as its one input")
        self._robot = robots[0]
        self._k = round(self._robot.state.timestamp_s / DT)  # the last step delivered
        self._reads = 0

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        # Its samples arrive delay_steps late: declared, so the run's clock check allows it.
        return {"force_n": ChannelInfo((2,), "N", 1.0 / DT, latency_s=self.config.delay_steps * DT)}

    def read(self) -> SampleBatch:
        self._reads += 1
        if self._reads == self.config.sigterm_at_read:
            os.kill(os.getpid(), signal.SIGTERM)
        if self._reads == self.config.stuck_at_read:
            STUCK.append(HALTED.wait(self.config.stuck_for_s))
        cfg = self.config
        latest = round(self._robot.state.timestamp_s / DT) - cfg.delay_steps
        steps = np.arange(self._k + 1, latest + 1)
        self._k = max(self._k, latest)
        t = steps * DT
        if cfg.silent_as == "missing":
            t = t[t <= cfg.silent_from_s + 1e-9]
        magnitude = np.where(t >= cfg.cross_at_s - 1e-9, cfg.peak_n, cfg.force_n)
        force = np.column_stack([magnitude * 0.6, magnitude * 0.8])  # |(0.6, 0.8)| = 1
        valid = t <= cfg.silent_from_s + 1e-9
        force[~valid] = np.nan
        return SampleBatch(t, {"force_n": force}, {"force_n": valid})

    def checkpoint(self) -> tuple[int, int]:
        return self._k, self._reads

    def rewind(self, checkpoint: tuple[int, int]) -> None:
        self._k, self._reads = checkpoint

    def reset(self) -> None:
        pass

    def close(self) -> None:
        EVENTS.append(("close", self.id))


class LinesConfig(PluginConfig):
    lines: list[tuple[float, float, float, float]] = Field(
        default_factory=lambda: [(0.1, 0.2, 0.3, 0.2)] * 3,
        description="(x0, y0, x1, y1) of each movement, in order.")
    speed_m_per_s: float = Field(0.1, gt=0, description="Speed of every movement.")


class LinesPlanner(Planner):
    """Proposes the configured lines, then stops."""

    def __init__(self, config: LinesConfig, context: Any) -> None:
        super().__init__(config, context)
        self._next = 0

    def propose(self) -> ExploratoryMovement | None:
        if self._next >= len(self.config.lines):
            return None
        x0, y0, x1, y1 = self.config.lines[self._next]
        self._next += 1
        speed = self.config.speed_m_per_s
        return ExploratoryMovement(np.array([x0, y0]), np.array([x1, y1]), speed)

    def on_movement_end(self, result: MovementResult) -> None:
        RESULTS.append(result)


@hookimpl
def hapticframe_robots() -> Iterator[RobotSpec]:
    yield RobotSpec("lab-arm", "A device arm on a step clock.", ArmConfig, f"{__name__}:LabArm")


@hookimpl
def hapticframe_sensors() -> Iterator[SensorSpec]:
    yield SensorSpec("lab-scripted-force", "A force sensor with a known script.",
                     ScriptedForceConfig, f"{__name__}:ScriptedForceSensor")


@hookimpl
def hapticframe_planners() -> Iterator[PlannerSpec]:
    yield PlannerSpec("lab-lines", "The configured lines.", LinesConfig,
                      f"{__name__}:LinesPlanner", inputs=())
