"""Reading calibration recordings from recorded runs (issue 32 §2).

A calibration run is an ordinary run of an experiment whose scene holds the object the lab
buried where it knows it, recorded with ``run.halt_on_interaction: false`` so that the
movements run on through jamming. :func:`read_calibration_run` turns its ``trace.npz``
(the robot's position and heading), ``ground_truth.npz`` (depth, movement index and the
world's states) and ``run.json`` (the scene) into a
:class:`~hapticframe.kinds.CalibrationRecording`. The class of each sample is the recorded
state as a one-hot row over ``free``, ``jamming``, ``contact``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from hapticframe._scene import Scene
from hapticframe.kinds._calibration import CalibrationRecording

__all__ = ["CALIBRATION_CLASSES", "read_calibration_run"]

#: Class names of a recorded state 0, 1, 2.
CALIBRATION_CLASSES: tuple[str, ...] = ("free", "jamming", "contact")


def read_calibration_run(run_dir: str | Path, robot: str = "arm") -> CalibrationRecording:
    """The calibration recording of a recorded run with ground truth.

    Parameters
    ----------
    run_dir : path
        A run's output directory.
    robot : str
        The recorded robot's id (its ``robot/<id>/...`` trace channels).

    Returns
    -------
    CalibrationRecording

    Raises
    ------
    ValueError
        Naming the run and the file that is missing or lacks an array, or a run with no
        scene objects.
    """
    run_dir = Path(run_dir)
    try:
        with np.load(run_dir / "trace.npz", allow_pickle=False) as trace:
            position = np.asarray(trace[f"robot/{robot}/position_m"], dtype=np.float64)
            heading = np.asarray(trace[f"robot/{robot}/heading_rad"], dtype=np.float64)
        with np.load(run_dir / "ground_truth.npz", allow_pickle=False) as truth:
            depth = np.asarray(truth["depth_m"], dtype=np.float64)
            state = np.asarray(truth["state"]).astype(np.int64)
            movement = np.asarray(truth["movement_index"]).astype(np.int64)
            times = (np.asarray(truth["timestamps_s"], dtype=np.float64)
                     if "timestamps_s" in truth.files
                     else np.arange(len(state), dtype=np.float64))
        scene = json.loads((run_dir / "run.json").read_text())["resolved_config"]["scene"]
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise ValueError(f"{run_dir}: not a recorded run with ground truth "
                         f"({type(exc).__name__}: {exc})") from exc
    if scene is None:
        raise ValueError(f"{run_dir}/run.json: the run has no scene (no buried objects)")
    objects = Scene.model_validate(scene).objects
    if not objects:
        raise ValueError(f"{run_dir}/run.json: the run's scene has no buried objects")
    if state.size and (state.min() < 0 or state.max() >= len(CALIBRATION_CLASSES)):
        raise ValueError(f"{run_dir}/ground_truth.npz: state must be 0, 1 or 2")
    probabilities = np.eye(len(CALIBRATION_CLASSES), dtype=np.float64)[state]
    return CalibrationRecording(
        times, position[:, :2] if position.ndim == 2 else position, heading, depth, movement,
        probabilities, CALIBRATION_CLASSES, [o.outline() for o in objects],
        source=str(run_dir),
    )
