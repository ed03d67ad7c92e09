"""The check of :meth:`Component.checkpoint` / :meth:`Component.rewind` (look-ahead support).

A closed loop that looks ahead (``run.lookahead_steps``) rewinds the robot, the streamed
sensors, the feature extractors and the classifiers when a batch holds an interaction, and
replays the steps one at a time. That is only correct if rewinding restores the state
exactly: the replay must give the very numbers the first pass gave.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hapticframe._kind import Kind
from hapticframe._registry import Registry
from hapticframe._specs import PluginSpec
from hapticframe.kinds import Component, Robot, Sensor
from hapticframe.run._components import INTERFACES
from hapticframe.testing._common import check, outputs_equal
from hapticframe.testing._harness import (
    DEFAULT_SCENE,
    CheckFailure,
    crossing_movement,
    make_component,
    release_component,
    synthetic_batch,
)
from hapticframe.testing._streams import _outputs

__all__ = ["check_rewind"]

#: Steps, reads or chunks run before the checkpoint and between checkpoint and rewind.
_BEFORE, _AHEAD = 5, 40


def _robot_trace(robot: Robot, steps: int) -> list[Any]:
    out: list[Any] = []
    for _ in range(steps):
        state = robot.step()
        if state is None:
            out.append(None)
            break
        out.append((state.timestamp_s, state.position_m, state.heading_rad, state.depth_m,
                    state.speed_m_per_s))
    out.append(robot.halt_reason)
    return out


def _sensor_trace(sensor: Sensor, robot: Robot | None, reads: int) -> list[Any]:
    out: list[Any] = []
    for _ in range(reads):
        if robot is not None and robot.step() is None:
            break
        if sensor.exhausted:
            break
        batch = sensor.read()
        out.append((batch.timestamps_s, dict(batch.channels), dict(batch.valid)))
    return out


def _checkpoints(components: list[Component]) -> list[Any] | None:
    """Snapshots of every component, or None when one of them cannot rewind."""
    snapshots = [c.checkpoint() for c in components]
    return None if any(s is None for s in snapshots) else snapshots


def _rewound(components: list[Component], snapshots: list[Any], what: str) -> None:
    try:
        for component, snapshot in zip(components, snapshots, strict=True):
            component.rewind(snapshot)
    except Exception as exc:
        raise CheckFailure(f"rewind() raised {type(exc).__name__}: {exc} ({what})") from exc


@check(Kind.ROBOT, Kind.SENSOR, Kind.FEATURE_EXTRACTOR, Kind.CLASSIFIER)
def check_rewind(spec: PluginSpec, *, registry: Registry | None = None) -> None:
    """A component whose ``checkpoint()`` returns a snapshot replays exactly after ``rewind``.

    Components that return None (the default: cannot rewind) pass without further checks.
    """
    component = make_component(spec, registry=registry, seed=5, interface=INTERFACES[spec.kind])
    try:
        if isinstance(component, Robot):
            robot = component
            robot.begin(crossing_movement(DEFAULT_SCENE))
            _robot_trace(robot, _BEFORE)
            snapshots = _checkpoints([robot])
            if snapshots is None:
                return
            first = _robot_trace(robot, _AHEAD)
            _rewound([robot], snapshots, "robot")
            second = _robot_trace(robot, _AHEAD)
        elif isinstance(component, Sensor):
            sensor = component
            robots = [c for c in sensor.context.inputs.values() if isinstance(c, Robot)]
            robot_in = robots[0] if robots else None
            if robot_in is not None:
                robot_in.begin(crossing_movement(sensor.context.scene))
            _sensor_trace(sensor, robot_in, _BEFORE)
            # The loop rewinds the robot a simulated sensor reads from together with it.
            chain: list[Component] = [sensor] + ([robot_in] if robot_in is not None else [])
            snapshots = _checkpoints(chain)
            if snapshots is None:
                return
            first = _sensor_trace(sensor, robot_in, _AHEAD)
            _rewound(chain, snapshots, "sensor")
            second = _sensor_trace(sensor, robot_in, _AHEAD)
        else:
            batch = synthetic_batch(spec, 400, rng=np.random.default_rng(4))
            chunks = [batch.select(slice(s, s + 25)) for s in range(0, 400, 25)]
            for chunk in chunks[:4]:
                _outputs(component, chunk)
            snapshots = _checkpoints([component])
            if snapshots is None:
                return
            first = [_outputs(component, chunk) for chunk in chunks[4:]]
            _rewound([component], snapshots, spec.kind.value)
            second = [_outputs(component, chunk) for chunk in chunks[4:]]
    finally:
        release_component(component)
    if not outputs_equal(first, second):
        raise CheckFailure(
            "after rewind() to a checkpoint the component gave other outputs than the first "
            "time from that checkpoint: checkpoint() must capture all the state that stepping "
            "changes (random generators included)"
        )
