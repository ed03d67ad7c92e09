"""Figures of the raking estimator (matplotlib, the ``plots`` extra)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from ._model import ObjectEstimate

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = ["CLASS_NOTE", "DEPTH_MEANING", "DIRECTION_MEANING", "estimate_figure",
           "save_estimate_figure"]

#: What each class task is. The data set's README gives the codes only (direction label
#: 0/1/2, depth label 0/1, distance label in mm); the words here are ours.
DIRECTION_MEANING = "direction: where the buried object lies from the rake, 3 classes (0, 1, 2)"
DEPTH_MEANING = "depth: how deep the object is buried, 2 classes (0, 1)"
#: What the source does not say, and why the recordings cannot tell it either.
CLASS_NOTE = ("The data set codes the classes 0, 1, 2 and 0, 1 only: which side or depth each "
              "code stands for it does not say (the tool's path and height are the same in "
              "every class).")

#: Vertical offset of the label's track and the estimate's track from the class's level.
_TRACK_OFFSET = 0.14


def _with_breaks(t: NDArray[np.float64], y: NDArray[np.float64]
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """``t`` and ``y`` with a NaN between trials (a pause of over 5 sample steps), so that a
    line does not join the end of one trial to the start of the next."""
    if len(t) < 3:
        return t, y
    dt = np.diff(t)
    breaks = np.flatnonzero(dt > 5.0 * float(np.median(dt))) + 1
    return (np.insert(t.astype(np.float64), breaks, np.nan),
            np.insert(y.astype(np.float64), breaks, np.nan))


def _class_panel(ax: Axes, t: NDArray[np.float64], proba: NDArray[np.float64],
                 truth: NDArray[np.float64] | None, meaning: str) -> None:
    """The most probable class (the estimate) beside the labelled class (the truth)."""
    n = proba.shape[1]
    estimate = proba.argmax(axis=1).astype(np.float64)
    title = meaning
    if truth is not None:
        label = np.rint(truth).astype(np.float64)
        ax.plot(*_with_breaks(t, label + _TRACK_OFFSET), color="k", lw=2.5,
                label="labelled class (truth)")
        agree = float(np.mean(estimate == label))
        title += f"; the estimate is the label at {100.0 * agree:.1f} % of samples"
    ax.plot(t, estimate - _TRACK_OFFSET, ls="none", marker="|", ms=5, color="tab:blue",
            label="most probable class (estimate)")
    ax.set_yticks(range(n), [f"class {k}" for k in range(n)])
    ax.set_ylim(-0.5, n - 0.5)
    ax.set_title(title, fontsize=9, loc="left")
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8)


def estimate_figure(t: NDArray[np.float64], est: ObjectEstimate,
                    true_distance_mm: NDArray[np.float64] | None,
                    true_direction: NDArray[np.float64] | None = None,
                    true_depth: NDArray[np.float64] | None = None) -> Figure:
    """The estimates of a stream beside the truth where it is known.

    Top: the distance estimate with ±1 std and the labelled distance. Then direction and
    depth: the most probable class beside the labelled class, on axes that name the
    classes (what each task is in the panel's title, what the source leaves unsaid in the
    figure's caption). Legends sit right of their panels, so they hide no data.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Sample times (s).
    est : ObjectEstimate
        The estimates of those samples.
    true_distance_mm, true_direction, true_depth : ndarray, shape (n,), optional
        The labels streamed with the samples; None: not known (not drawn).

    Returns
    -------
    matplotlib.figure.Figure
        Needs matplotlib (the ``plots`` extra).
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(3, 1, figsize=(11, 7.5), sharex=True, layout="constrained")
    ax = axes[0]
    ax.fill_between(*_with_breaks(t, est.distance_mm - est.distance_std_mm),
                    _with_breaks(t, est.distance_mm + est.distance_std_mm)[1],
                    alpha=0.3, label="estimate ±1 std")
    ax.plot(*_with_breaks(t, est.distance_mm), lw=1, label="estimated distance")
    title = "distance from the tool to the buried object"
    if true_distance_mm is not None:
        ax.plot(*_with_breaks(t, true_distance_mm), color="k", lw=1.5,
                label="labelled distance (truth)")
        mae = float(np.mean(np.abs(est.distance_mm - true_distance_mm)))
        title += f"; mean absolute error {mae:.1f} mm"
    ax.set_ylabel("distance (mm)")
    ax.set_title(title, fontsize=9, loc="left")
    ax.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8)
    _class_panel(axes[1], t, est.direction_proba, true_direction, DIRECTION_MEANING)
    _class_panel(axes[2], t, est.depth_proba, true_depth, DEPTH_MEANING)
    axes[-1].set_xlabel("time (s, nominal rate; trials one after the other)")
    fig.suptitle(CLASS_NOTE, fontsize=8)
    return fig


def save_estimate_figure(path: Path, t: NDArray[np.float64], est: ObjectEstimate,
                         true_distance_mm: NDArray[np.float64] | None,
                         true_direction: NDArray[np.float64] | None = None,
                         true_depth: NDArray[np.float64] | None = None) -> bool:
    """Write :func:`estimate_figure` to ``path`` (PNG); False without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig = estimate_figure(t, est, true_distance_mm, true_direction, true_depth)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
