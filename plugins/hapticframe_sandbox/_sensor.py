"""The sandbox force sensor: the simulated fingertip force plus measurement noise."""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from hapticframe.kinds import BuildContext, ChannelInfo, SampleBatch, Sensor

from ._config import SandboxForceSensorConfig
from ._robot import SandboxRobot

__all__ = ["FORCE_CHANNEL", "SandboxForceSensor"]

FORCE_CHANNEL = "force_n"


class SandboxForceSensor(Sensor):
    """Reads the 2-D interaction force of a :class:`SandboxRobot`, one sample per robot step.

    Parameters
    ----------
    config : SandboxForceSensorConfig
    context : BuildContext
        ``inputs`` must hold exactly one component: the sandbox robot.
    """

    def __init__(self, config: SandboxForceSensorConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        robots = list(context.inputs.values())
        if len(robots) != 1 or not isinstance(robots[0], SandboxRobot):
            found = ", ".join(f"{k!r} ({type(v).__name__})" for k, v in context.inputs.items())
            raise ValueError(
                f"sensor {context.id!r} (type 'sandbox-force') needs exactly one input, a robot "
                f"of type 'sandbox'; got [{found}]"
            )
        self._robot: SandboxRobot = robots[0]
        self._rng = context.rng
        # Samples start with the robot's next step: earlier steps were never "measured".
        self._cursor = self._robot.steps_taken
        self._channels = MappingProxyType(
            {FORCE_CHANNEL: ChannelInfo(shape=(2,), unit="N", rate_hz=self._robot.control_rate_hz)}
        )

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def robot(self) -> SandboxRobot:
        return self._robot

    def read(self) -> SampleBatch:
        """Noisy force samples for the robot steps since the previous read (maybe none)."""
        if self._robot.steps_taken == self._cursor + 1:
            # A closed loop reads after every step: one sample, built from plain floats
            # (the same draws and sums as the array path below).
            t, (fx, fy) = self._robot.true_force_of_step(self._cursor)
            self._cursor += 1
            scale = self.config.noise_std_n
            nx, ny = self._rng.standard_normal(2).tolist()
            return SampleBatch(
                np.array([t]), {FORCE_CHANNEL: np.array([[fx + scale * nx, fy + scale * ny]])}
            )
        timestamps, forces = self._robot.true_forces_since(self._cursor)
        self._cursor += timestamps.size
        if timestamps.size == 0:
            return SampleBatch.empty(self._channels)
        noise = self.config.noise_std_n * self._rng.standard_normal(forces.shape)
        return SampleBatch(timestamps, {FORCE_CHANNEL: forces + noise})

    def checkpoint(self) -> tuple[int, Mapping[str, Any]]:
        """The read cursor and the noise generator's state."""
        return self._cursor, self._rng.bit_generator.state

    def rewind(self, checkpoint: tuple[int, Mapping[str, Any]]) -> None:
        self._cursor, generator = checkpoint
        self._rng.bit_generator.state = generator

    def reset(self) -> None:
        """Drop unread samples: the next read starts with the robot's next step."""
        self._cursor = self._robot.steps_taken
