"""Reading calibration recordings from recorded runs (issue 32 §2).

A calibration run is an ordinary run of an experiment whose scene holds the object the lab
buried where it knows it, recorded with ``run.halt_on_interaction: false`` so that the
movements run on through jamming. :func:`read_calibration_run` turns its ``trace.npz``
(the robot's position, heading, depth and movement index, and what each classifier
reported) and ``run.json`` (the scene) into a
:class:`~hapticframe.kinds.CalibrationRecording`.

The class of each sample is what the named classifier reported during the run (its
recorded ``classifier/<id>/probabilities``, the latest output not after each robot step):
a sensor model learns the likelihood of what the classifier *says*, which is what a search
will feed it. Without a classifier, or where the run recorded none of that id, it is the
world's recorded true state (``ground_truth.npz``, a simulation's) as a one-hot row over
``free``, ``jamming``, ``contact``.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from hapticframe._scene import Scene
from hapticframe.kinds._calibration import CalibrationRecording

__all__ = ["CALIBRATION_CLASSES", "read_calibration_run"]

#: Class names of a recorded state 0, 1, 2.
CALIBRATION_CLASSES: tuple[str, ...] = ("free", "jamming", "contact")


def read_calibration_run(run_dir: str | Path, robot: str | None = "arm",
                         classifier: str | None = None) -> CalibrationRecording:
    """The calibration recording of a recorded run.

    Parameters
    ----------
    run_dir : path
        A run's output directory (``trace.npz``, ``run.json``; ``ground_truth.npz`` where
        the classes are the true states).
    robot : str or None
        The recorded robot's id (its ``robot/<id>/...`` trace channels); None takes the
        only robot the trace holds.
    classifier : str, optional
        The classifier whose recorded outputs are the classes. None, or a run that did not
        record it: the world's true states.

    Returns
    -------
    CalibrationRecording
        ``source`` says which classes it holds (``run_dir (classifier 'id')`` or
        ``run_dir (true state)``).

    Raises
    ------
    ValueError
        Naming the run and the file that is missing or lacks an array, a trace of several
        robots with none named, or a run with no scene objects.
    """
    run_dir = Path(run_dir)
    try:
        with np.load(run_dir / "trace.npz", allow_pickle=False) as trace:
            robot = _the_robot(trace.files, robot, run_dir)
            key = f"robot/{robot}"
            times = np.asarray(trace[f"{key}/timestamps_s"], dtype=np.float64)
            position = np.asarray(trace[f"{key}/position_m"], dtype=np.float64)
            heading = np.asarray(trace[f"{key}/heading_rad"], dtype=np.float64)
            depth = (np.asarray(trace[f"{key}/depth_m"], dtype=np.float64)
                     if f"{key}/depth_m" in trace.files else None)
            movement = (np.asarray(trace[f"{key}/movement_index"]).astype(np.int64)
                        if f"{key}/movement_index" in trace.files else None)
            recorded = (classifier is not None
                        and f"classifier/{classifier}/probabilities" in trace.files)
            if recorded:
                c_key = f"classifier/{classifier}"
                c_times = np.asarray(trace[f"{c_key}/timestamps_s"], dtype=np.float64)
                c_probs = np.asarray(trace[f"{c_key}/probabilities"], dtype=np.float64)
                classes = tuple(str(c) for c in trace[f"{c_key}/classes"])
        scene = json.loads((run_dir / "run.json").read_text())["resolved_config"]["scene"]
        if not recorded or depth is None or movement is None:
            with np.load(run_dir / "ground_truth.npz", allow_pickle=False) as truth:
                depth = np.asarray(truth["depth_m"], dtype=np.float64) if depth is None else depth
                movement = (np.asarray(truth["movement_index"]).astype(np.int64)
                            if movement is None else movement)
                state = None if recorded else np.asarray(truth["state"]).astype(np.int64)
    except (OSError, KeyError, ValueError, TypeError) as exc:
        raise ValueError(f"{run_dir}: not a recorded run with robot poses and classes "
                         f"({type(exc).__name__}: {exc})") from exc
    if scene is None:
        raise ValueError(f"{run_dir}/run.json: the run has no scene (no buried objects)")
    objects = Scene.model_validate(scene).objects
    if not objects:
        raise ValueError(f"{run_dir}/run.json: the run's scene has no buried objects")
    positions = position[:, :2] if position.ndim == 2 else position
    if recorded:
        # The classifier's latest output not after each robot step; steps before its first
        # output have no class and are left out.
        index = np.searchsorted(c_times, times, side="right") - 1
        keep = index >= 0
        probabilities = c_probs[index[keep]]
        times, positions, heading = times[keep], positions[keep], heading[keep]
        depth, movement = depth[keep], movement[keep]
        source = f"{run_dir} (classifier {classifier!r})"
    else:
        assert state is not None  # read with the truth above
        if state.size and (state.min() < 0 or state.max() >= len(CALIBRATION_CLASSES)):
            raise ValueError(f"{run_dir}/ground_truth.npz: state must be 0, 1 or 2")
        probabilities = np.eye(len(CALIBRATION_CLASSES), dtype=np.float64)[state]
        classes = CALIBRATION_CLASSES
        source = f"{run_dir} (true state)"
    return CalibrationRecording(
        times, positions, heading, depth, movement, probabilities, classes,
        [o.outline() for o in objects], source=source,
    )


def _the_robot(files: Any, robot: str | None, run_dir: Path) -> str:
    """``robot``, or the only robot a trace holds."""
    if robot is not None:
        return robot
    robots = sorted({name.split("/")[1] for name in files
                     if name.startswith("robot/") and name.endswith("/position_m")})
    if len(robots) != 1:
        raise ValueError(f"{run_dir}/trace.npz: {len(robots)} robots recorded "
                         f"({', '.join(robots) or 'none'}); name the robot")
    return str(robots[0])
