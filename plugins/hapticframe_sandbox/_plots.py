"""The sandbox's run figure: fingertip force per exploratory movement (like thesis Fig. 3.6)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ._robot import GroundTruthLog, MovementTruth

__all__ = ["plot_movement_forces"]


def plot_movement_forces(
    log: GroundTruthLog, movements: Sequence[MovementTruth], path: Path
) -> Path | None:
    """Write force magnitude against time for every movement, with jamming onsets marked.

    Left: time since each movement started, jamming (circle) and contact (cross) onsets
    marked. Right: movements that jammed, aligned at the jamming onset (dashed line at 0 s).

    Returns
    -------
    Path or None
        The written file, or None when matplotlib is not installed (a warning says so).
    """
    try:
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure
    except ImportError:  # plots are an optional extra
        warnings.warn("matplotlib is not installed; forces.png was not written", stacklevel=2)
        return None
    path.parent.mkdir(parents=True, exist_ok=True)
    # Figure + Agg canvas directly: no pyplot, so no global backend or figure state is touched.
    fig = Figure(figsize=(11, 4.2), layout="constrained")
    FigureCanvasAgg(fig)
    ax_all, ax_aligned = fig.subplots(1, 2)
    magnitude = log.force_magnitude_n
    colors = [f"C{i % 10}" for i in range(max(1, len(movements)))]
    for truth, color in zip(movements, colors):
        rows = log.movement_index == truth.index
        if not rows.any():
            continue
        t = log.timestamps_s[rows]
        f = magnitude[rows]
        label = f"EM {truth.index + 1} (d={100 * truth.depth_m:.2f} cm)"
        ax_all.plot(t - truth.start_time_s, f, color=color, lw=1.0, label=label)
        for onset, marker in ((truth.jamming_onset_s, "o"), (truth.contact_onset_s, "x")):
            if not math.isnan(onset):
                k = int(np.searchsorted(t, onset))
                ax_all.plot(onset - truth.start_time_s, f[min(k, f.size - 1)], marker, color=color)
        if not math.isnan(truth.jamming_onset_s):
            ax_aligned.plot(t - truth.jamming_onset_s, f, color=color, lw=1.0, label=label)
    ax_aligned.axvline(0.0, color="k", ls="--", lw=1.0)
    for ax in (ax_all, ax_aligned):
        ax.set_ylabel("fingertip force (N)")
        ax.grid(alpha=0.3)
    ax_all.set_xlabel("time since movement start (s)")
    ax_all.set_title("force per movement (o jamming onset, x contact)")
    ax_aligned.set_xlabel("time since jamming onset (s)")
    ax_aligned.set_title("movements that jammed, aligned at onset")
    if movements:
        ax_all.legend(fontsize=7, loc="upper left")
    fig.savefig(path, dpi=110)
    return path
