"""Fit the sandbox's taxel measurement model (``sandbox-taxels``) to the real trials.

Run ``python -m hapticframe_raking._sandbox_calibration`` (or call
:func:`calibrate_sandbox_taxels`) to print the fitted numbers that
``hapticframe_sandbox.SandboxTaxelSensorConfig`` ships as its defaults.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from hapticframe import Circle, Ellipse, Polygon, Scene
from hapticframe.kinds import BuildContext, MovementResult

from ._data import load_trials

__all__ = ["calibrate_sandbox_taxels", "sandbox_approach_forces"]


def sandbox_approach_forces(approaches: int, seed: int) -> dict[str, np.ndarray]:
    """Per step of ``approaches`` straight sandbox approaches at an 8 cm circle and a
    9 x 5 cm ellipse (the thesis's objects): ``along``, ``across`` (N), ``distance_mm``,
    ``direction`` (the labels of ``sandbox-taxels`` with its default settings)."""
    from hapticframe_sandbox import (
        SandboxRobot,
        SandboxRobotConfig,
        SandboxTaxelSensorConfig,
        approach_movement,
        force_components,
        raking_labels,
    )

    rng = np.random.default_rng(seed)
    objects: list[Circle | Ellipse | Polygon] = [Circle(center_m=(0.2, 0.25), radius_m=0.04),
               Ellipse(center_m=(0.55, 0.25), semi_axes_m=(0.045, 0.025), orientation_deg=35)]
    robot = SandboxRobot(SandboxRobotConfig(), BuildContext(
        id="arm", rng=np.random.default_rng(rng.integers(2**32)), scene=Scene(objects=objects)))
    labels_cfg = SandboxTaxelSensorConfig()
    outlines = [np.asarray(o.outline(256)) for o in objects]
    parts: dict[str, list[np.ndarray]] = {"along": [], "across": [], "distance_mm": [],
                                          "direction": []}
    for k in range(approaches):
        movement = approach_movement(rng, objects[k % 2], standoff_m=0.15)
        robot.begin(movement)
        first = robot.steps_taken
        while robot.step() is not None:
            pass
        truth = robot.ground_truth
        heading = np.full(len(truth) - first, movement.heading_rad)
        along, across = force_components(truth.forces_n[first:], heading)
        distance, direction, _ = raking_labels(
            truth.positions_m[first:], heading, truth.depth_m[first:], outlines,
            direction_split_deg=labels_cfg.direction_split_deg, deep_m=labels_cfg.deep_m)
        for key, value in (("along", along), ("across", across),
                           ("distance_mm", distance), ("direction", direction)):
            parts[key].append(value)
        robot.on_movement_end(MovementResult(index=k, movement=movement,
                                             halted=bool(robot.halt_reason),
                                             halt_reason=robot.halt_reason,
                                             final_state=robot.state))
    return {k: np.concatenate(v) for k, v in parts.items()}


def calibrate_sandbox_taxels(approaches: int = 40, seed: int = 7) -> dict[str, Any]:
    """The ``sandbox-taxels`` model fitted on the 80 real training trials.

    Returns the four config fields (twelve numbers each, rounded to 4 decimals) and the
    sample counts used.
    """
    from hapticframe_sandbox import fit_taxel_model

    trials = load_trials("training")
    sim = sandbox_approach_forces(approaches, seed)
    # The sensor's own noise: sample-to-sample differences, over sqrt(2) (white noise).
    steps = np.concatenate([np.diff(t.force.reshape(-1, 12), axis=0) for t in trials])
    sample_noise = steps.std(axis=0) / np.sqrt(2.0)
    model = fit_taxel_model(
        np.concatenate([t.force for t in trials]),
        np.concatenate([t.distance_mm for t in trials]),
        np.concatenate([t.direction for t in trials]),
        sim["along"], sim["across"], sim["distance_mm"], sim["direction"].astype(np.int64),
        noise_floor=sample_noise)

    def twelve(a: np.ndarray) -> list[float]:
        return [round(float(v), 4) for v in a.reshape(12)]

    return {"offset": twelve(model.offset), "gain_along_per_n": twelve(model.gain_along_per_n),
            "gain_across_per_n": twelve(model.gain_across_per_n),
            "noise_std": twelve(model.noise_std),
            "real_samples": int(sum(len(t) for t in trials)),
            "sandbox_samples": len(sim["along"]), "approaches": approaches, "seed": seed}


if __name__ == "__main__":
    print(json.dumps(calibrate_sandbox_taxels(), indent=1))
