"""Labelled simulated runs: approach movements and recordings with ground-truth states.

These drive a :class:`SandboxRobot` and its :class:`SandboxForceSensor` without the core's
run loop, to calibrate and evaluate interaction classifiers on known truth.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hapticframe.kinds import ExploratoryMovement, MovementResult, SampleBatch, concatenate_batches

from ._robot import SandboxRobot
from ._sensor import SandboxForceSensor

__all__ = ["approach_movement", "record_movements"]


def approach_movement(
    rng: np.random.Generator,
    scene_object: Any,
    *,
    standoff_m: float = 0.15,
    lateral_fraction: float = 0.8,
    speed_m_per_s: float = 0.05,
    depth_m: float | None = None,
) -> ExploratoryMovement:
    """A straight movement in a random direction that runs into ``scene_object``.

    The path passes the object's centroid at a random lateral offset of up to
    ``lateral_fraction`` times the object's smallest centroid-to-outline distance, so for a
    convex object the plate is certain to reach it. It starts ``standoff_m`` outside the
    object's bounding circle and ends as far beyond it.

    Parameters
    ----------
    rng : numpy.random.Generator
    scene_object : Circle, Ellipse or Polygon
        Any scene object with ``centroid_m`` and ``outline``.
    standoff_m : float
        Free travel before the bounding circle; longer than the rupture distance keeps the
        start free of jamming.
    lateral_fraction : float
        In [0, 1).
    speed_m_per_s : float
    depth_m : float or None
        Commanded depth; None lets the robot use its schedule.
    """
    if not 0.0 <= lateral_fraction < 1.0:
        raise ValueError("lateral_fraction must lie in [0, 1)")
    centre = np.asarray(scene_object.centroid_m, dtype=np.float64)
    distances = np.linalg.norm(scene_object.outline(512) - centre, axis=1)
    inner, outer = float(distances.min()), float(distances.max())
    heading = rng.uniform(0.0, 2.0 * np.pi)
    along = np.array([np.cos(heading), np.sin(heading)])
    across = np.array([-along[1], along[0]])
    offset = lateral_fraction * inner * rng.uniform(-1.0, 1.0)
    through = centre + offset * across
    reach = outer + standoff_m
    return ExploratoryMovement(
        start_m=through - reach * along,
        end_m=through + reach * along,
        speed_m_per_s=speed_m_per_s,
        depth_m=depth_m,
        phase="approach",
        label=f"approach heading {np.degrees(heading):.0f} deg",
    )


def record_movements(
    robot: SandboxRobot,
    sensor: SandboxForceSensor,
    movements: Iterable[ExploratoryMovement],
) -> list[tuple[SampleBatch, NDArray[np.int64]]]:
    """Run each movement to its end (or the force limit) and return sensor data with truth.

    The sensor is read after every robot step, as the run loop does. Each movement yields
    one ``(batch, labels)`` pair: the sensor samples and the simulator's true state per sample
    (0 free, 1 jamming, 2 contact). The robot is told each movement ended, so its depth
    schedule advances exactly as in a run.
    """
    out: list[tuple[SampleBatch, NDArray[np.int64]]] = []
    for index, movement in enumerate(movements):
        robot.begin(movement)
        first = robot.steps_taken
        batches = []
        while robot.step() is not None:
            batches.append(sensor.read())
        batches = [b for b in batches if len(b)]
        batch = concatenate_batches(batches) if batches else SampleBatch.empty(sensor.channels)
        truth = robot.ground_truth
        labels = truth.states[first:]
        if not np.array_equal(truth.timestamps_s[first:], batch.timestamps_s):
            raise RuntimeError("sensor samples do not line up with robot steps")
        robot.on_movement_end(
            MovementResult(
                index=index,
                movement=movement,
                halted=bool(robot.halt_reason),
                halt_reason=robot.halt_reason,
                final_state=robot.state,
            )
        )
        out.append((batch, labels))
    return out
