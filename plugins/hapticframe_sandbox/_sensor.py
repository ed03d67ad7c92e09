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

    Given several sandbox robots (arms that share one sandbox), it reads the force of the
    arm that moves: the samples of every arm's steps since the previous read, in time order
    (the arms share the sandbox's clock, so their steps never coincide). That is the one
    force stream a classifier needs: each movement's force from the fingertip that made it.

    Parameters
    ----------
    config : SandboxForceSensorConfig
    context : BuildContext
        ``inputs`` must hold one or more components, each a sandbox robot.
    """

    def __init__(self, config: SandboxForceSensorConfig, context: BuildContext) -> None:
        super().__init__(config, context)
        robots = [r for r in context.inputs.values() if isinstance(r, SandboxRobot)]
        if not robots or len(robots) != len(context.inputs):
            found = ", ".join(f"{k!r} ({type(v).__name__})" for k, v in context.inputs.items())
            raise ValueError(
                f"sensor {context.id!r} (type 'sandbox-force') needs one input, a robot "
                f"of type 'sandbox' (or several that share a sandbox); got [{found}]"
            )
        self._robots: list[SandboxRobot] = robots
        if len(robots) > 1:
            shared = robots[0].sandbox_robots
            distinct = len({id(r) for r in robots}) == len(robots)
            if not distinct or not all(any(r is o for o in shared) for r in robots):
                raise ValueError(
                    f"sensor {context.id!r} (type 'sandbox-force'): its robots must be distinct "
                    "and share one sandbox (name the first robot in the others' inputs)"
                )
        self._robot: SandboxRobot = robots[0]
        self._rng = context.rng
        # Samples start with the robot's next step: earlier steps were never "measured".
        self._cursor = self._robot.steps_taken
        self._cursors = [r.steps_taken for r in robots]
        self._channels = MappingProxyType(
            {FORCE_CHANNEL: ChannelInfo(shape=(2,), unit="N", rate_hz=self._robot.control_rate_hz)}
        )

    @property
    def channels(self) -> Mapping[str, ChannelInfo]:
        return self._channels

    @property
    def robot(self) -> SandboxRobot:
        """The (first) robot it reads."""
        return self._robot

    @property
    def robots(self) -> tuple[SandboxRobot, ...]:
        """Every robot it reads."""
        return tuple(self._robots)

    def read(self) -> SampleBatch:
        """Noisy force samples for the robot steps since the previous read (maybe none)."""
        if len(self._robots) > 1:
            return self._read_several()
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

    def _read_several(self) -> SampleBatch:
        times, forces = [], []
        for k, robot in enumerate(self._robots):
            t, f = robot.true_forces_since(self._cursors[k])
            self._cursors[k] += t.size
            times.append(t)
            forces.append(f)
        timestamps = np.concatenate(times)
        if timestamps.size == 0:
            return SampleBatch.empty(self._channels)
        order = np.argsort(timestamps, kind="stable")
        true = np.concatenate(forces)[order]
        noise = self.config.noise_std_n * self._rng.standard_normal(true.shape)
        return SampleBatch(timestamps[order], {FORCE_CHANNEL: true + noise})

    def checkpoint(self) -> tuple[int, Mapping[str, Any], tuple[int, ...]]:
        """The read cursors and the noise generator's state."""
        return self._cursor, self._rng.bit_generator.state, tuple(self._cursors)

    def rewind(self, checkpoint: tuple[int, Mapping[str, Any], tuple[int, ...]]) -> None:
        self._cursor, generator, cursors = checkpoint
        self._cursors = list(cursors)
        self._rng.bit_generator.state = generator

    def reset(self) -> None:
        """Drop unread samples: the next read starts with the robot's next step."""
        self._cursor = self._robot.steps_taken
        self._cursors = [r.steps_taken for r in self._robots]
