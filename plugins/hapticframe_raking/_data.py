"""The real raking trials (Chen, Versace & Jamone, IROS 2024) and the paper's input sets.

The 100 trials ship with this package (``data/training.npz``: 80, ``data/testing.npz``: 20),
as ``hapticframe import`` wrote them from the authors' workbooks (``data/SOURCE.md``).
:func:`load_trials` reads either split, or any trace an import of the same layout wrote.

The paper's four input sets take from the 4 x 3 taxel forces (taxel i's x, y, z in the
authors' rows 3i-2, 3i-1, 3i): one taxel's normal force (``1_norm``), its three axes
(``1_3-axis``), the four normal forces (``4_norm``) or all twelve (``4_3-axis``), in the
order the authors' ``test_main.py`` slices their rows.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from hapticframe.bounded_io import BoundedReadError, open_regular, read_npz

__all__ = [
    "DIRECTION_CLASSES",
    "DEPTH_CLASSES",
    "INPUT_SETS",
    "RakingTrial",
    "data_path",
    "input_columns",
    "jamming_labels",
    "load_trials",
    "object_point",
    "write_jamming_labels",
    "select_inputs",
    "windows",
]

#: (taxel, axis) pairs of each input set, in the authors' row order.
INPUT_SETS: dict[str, tuple[tuple[int, int], ...]] = {
    "1_norm": ((0, 2),),
    "1_3-axis": ((0, 0), (0, 1), (0, 2)),
    "4_norm": ((0, 2), (1, 2), (2, 2), (3, 2)),
    "4_3-axis": tuple((t, a) for t in range(4) for a in range(3)),
}
InputSet = Literal["1_norm", "1_3-axis", "4_norm", "4_3-axis"]
DIRECTION_CLASSES = ("class_0", "class_1", "class_2")
DEPTH_CLASSES = ("class_0", "class_1")


@dataclass(frozen=True)
class RakingTrial:
    """One trial: forces ``(n, 4, 3)`` (normalized 0..1), labels and tool positions."""

    name: str
    force: NDArray[np.float64]
    distance_mm: NDArray[np.float64]
    direction: NDArray[np.int64]
    depth: NDArray[np.int64]
    position_m: NDArray[np.float64]

    def __len__(self) -> int:
        return int(self.force.shape[0])


def data_path(split: Literal["training", "testing"]) -> Path:
    """The shipped trace of one split."""
    return Path(str(resources.files("hapticframe_raking") / "data" / f"{split}.npz"))


def load_trials(source: str | Path, sensor: str = "tactile",
                robot: str = "tool") -> list[RakingTrial]:
    """Trials from ``source`` (``'training'``, ``'testing'`` or a trace.npz path)."""
    path = data_path(source) if source in ("training", "testing") else Path(source)  # type: ignore[arg-type]
    try:
        with open_regular(path) as handle:
            arrays = read_npz(handle)
    except (BoundedReadError, OSError) as exc:
        raise ValueError(f"cannot read raking trials from {path}: {exc}") from None
    s = f"sensor/{sensor}"
    try:
        force = np.asarray(arrays[f"{s}/taxel_force"], dtype=np.float64)
        distance = np.asarray(arrays[f"{s}/distance_mm"], dtype=np.float64)
        direction = np.asarray(arrays[f"{s}/direction_class"]).astype(np.int64)
        depth = np.asarray(arrays[f"{s}/depth_class"]).astype(np.int64)
        position = np.asarray(arrays[f"robot/{robot}/position_m"], dtype=np.float64)
        names = [str(n) for n in arrays["import/trial_names"]]
        starts = [int(i) for i in arrays["import/trial_starts"]]
    except KeyError as exc:
        raise ValueError(f"{path}: not a raking import (missing {exc})") from None
    if force.ndim != 3 or force.shape[1:] != (4, 3):
        raise ValueError(f"{path}: taxel_force has shape {force.shape}, expected (n, 4, 3)")
    bounds = list(zip(starts, starts[1:] + [force.shape[0]], strict=True))
    return [RakingTrial(name, force[a:b], distance[a:b], direction[a:b], depth[a:b],
                        position[a:b]) for name, (a, b) in zip(names, bounds, strict=True)]


def input_columns(input_set: str) -> tuple[tuple[int, int], ...]:
    try:
        return INPUT_SETS[input_set]
    except KeyError:
        raise ValueError(f"input set {input_set!r} is not one of "
                         f"{', '.join(INPUT_SETS)}") from None


def select_inputs(force: NDArray[np.float64], input_set: str) -> NDArray[np.float64]:
    """``(n, d)`` inputs of one input set from forces ``(n, 4, 3)``."""
    cols = input_columns(input_set)
    return np.stack([force[:, t, a] for t, a in cols], axis=1)


def windows(x: NDArray[np.float64], steps: int, *, pad: bool) -> NDArray[np.float64]:
    """Sliding windows ``(m, steps, d)`` ending at each step of ``x (n, d)``.

    ``pad=False``: the authors' windows, ending at steps ``steps-1 .. n-1`` (``m = n -
    steps + 1``). ``pad=True``: one window per step, the first sample repeated before the
    trial's start (what a streaming estimator sees at its first steps).
    """
    if pad:
        x = np.concatenate([np.repeat(x[:1], steps - 1, axis=0), x])
    n = x.shape[0] - steps + 1
    if n <= 0:
        return np.empty((0, steps, x.shape[1]))
    index = np.arange(steps)[None, :] + np.arange(n)[:, None]
    out: NDArray[np.float64] = x[index]
    return out


def object_point(trial: RakingTrial) -> NDArray[np.float64]:
    """The point ``(x0, y0)`` (m) the trial's distance labels are measured to.

    Least squares of ``1000 · hypot(x − x0, y − y0) = distance_mm`` over the trial's steps
    (the labels fit it within 0.06 mm on all 100 trials).
    """
    from scipy.optimize import least_squares

    x, y, d = trial.position_m[:, 0], trial.position_m[:, 1], trial.distance_mm / 1000.0

    def residual(p: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = np.hypot(x - p[0], y - p[1]) - d
        return out

    # Start beyond the trial's end along its direction of travel.
    travel = trial.position_m[-1, :2] - trial.position_m[0, :2]
    unit = travel / max(float(np.hypot(*travel)), 1e-12)
    start = trial.position_m[-1, :2] + unit * d[-1]
    fit = least_squares(residual, start)
    point: NDArray[np.float64] = fit.x
    return point


def jamming_labels(trial: RakingTrial, jamming_mm: float) -> NDArray[np.int64]:
    """Per step: 1 (jamming) where the labelled distance is at most ``jamming_mm``, else 0
    (free). The trials end before contact, so there is no contact class."""
    out: NDArray[np.int64] = (trial.distance_mm <= jamming_mm).astype(np.int64)
    return out


def write_jamming_labels(source: str | Path, jamming_mm: float, path: str | Path,
                         sensor: str = "tactile") -> None:
    """A labels file for the ``trace-recording`` sensor (``timestamps_s`` and ``state``):
    :func:`jamming_labels` of every trial of ``source``, at the trace's times."""
    trace = data_path(source) if source in ("training", "testing") else Path(source)  # type: ignore[arg-type]
    with open_regular(trace) as handle:
        t = np.asarray(read_npz(handle, keep=lambda k: k == f"sensor/{sensor}/timestamps_s")[
            f"sensor/{sensor}/timestamps_s"], dtype=np.float64)
    state = np.concatenate([jamming_labels(trial, jamming_mm)
                            for trial in load_trials(source, sensor)])
    np.savez_compressed(path, timestamps_s=t, state=state)
