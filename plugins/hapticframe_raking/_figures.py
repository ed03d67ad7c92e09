"""Figures of the raking estimator (matplotlib, the ``plots`` extra)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from ._model import ObjectEstimate

__all__ = ["save_estimate_figure"]


#: What the classes are, as the data set's README gives them: "direction label (0/1/2)" and
#: "depth label (0/1)"; it says no more (which bearing or depth each stands for).
CLASS_NOTE = ("classes as the data set labels them (its README: direction 0/1/2, depth 0/1; "
              "what each stands for is not given)")


def save_estimate_figure(path: Path, t: NDArray[np.float64], est: ObjectEstimate,
                         true_distance_mm: NDArray[np.float64] | None,
                         true_direction: NDArray[np.float64] | None = None,
                         true_depth: NDArray[np.float64] | None = None) -> bool:
    """Distance estimate with ±1 std and the truth; direction and depth probabilities with
    the labelled class shaded."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    ax = axes[0]
    ax.fill_between(t, est.distance_mm - est.distance_std_mm,
                    est.distance_mm + est.distance_std_mm, alpha=0.3, label="±1 std")
    ax.plot(t, est.distance_mm, lw=1, label="estimated distance")
    if true_distance_mm is not None:
        ax.plot(t, true_distance_mm, "k.", ms=2, label="labelled distance")
    ax.set_ylabel("distance to object (mm)")
    ax.legend(loc="upper right", fontsize=8)
    for ax, proba, name, truth in ((axes[1], est.direction_proba, "direction", true_direction),
                                   (axes[2], est.depth_proba, "depth", true_depth)):
        for k in range(proba.shape[1]):
            (line,) = ax.plot(t, proba[:, k], lw=1, label=f"P({name} class {k})")
            if truth is not None:
                ax.fill_between(t, 0, 1, where=np.rint(truth) == k, color=line.get_color(),
                                alpha=0.12, lw=0, label=f"labelled {name} class {k}")
        ax.set_ylabel(f"{name} probability")
        ax.set_ylim(-0.02, 1.02)
        ax.legend(loc="upper right", fontsize=7, ncol=2)
    axes[-1].set_xlabel("time (s, nominal rate; trials one after the other)")
    axes[0].set_title(CLASS_NOTE, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True
