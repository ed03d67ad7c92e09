"""The sandbox's run figure: fingertip force per exploratory movement (like thesis Fig. 3.6)."""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from hapticframe import plotting

from ._truth import GroundTruthLog, MovementTruth

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["draw_movement_forces", "plot_movement_forces"]

# Legend rows per column before the movements' legend wraps into another column.
_LEGEND_ROWS = 18
_PANELS_IN = (10.0, 4.2)
_LEGEND_COLUMN_IN = 1.55


def draw_movement_forces(log: GroundTruthLog, movements: Sequence[MovementTruth]) -> Figure:
    """Force magnitude against time for every movement, jamming and contact onsets marked.

    Left: time since each movement started; every jamming onset a circle, every contact
    onset a cross, in the movement's colour (each kind in the legend only when one
    happened). Right: movements that jammed, aligned at the jamming onset (dashed line at
    0 s). The legend beside the panels names each movement and its depth.
    """
    entries = len(movements) + 2
    columns = max(1, math.ceil(entries / _LEGEND_ROWS))
    width = _PANELS_IN[0] + columns * _LEGEND_COLUMN_IN
    figure = plotting.new_figure(width, _PANELS_IN[1])
    figure.subplots_adjust(left=0.6 / width, right=(_PANELS_IN[0] - 0.1) / width, bottom=0.12,
                           top=0.92, wspace=0.22)
    ax_all, ax_aligned = figure.subplots(1, 2)
    magnitude = log.force_magnitude_n
    # Ten colours repeat after ten movements; twenty keep up to twenty apart.
    palette = [f"C{i}" for i in range(10)] if len(movements) <= 10 else _tab20()
    onsets: dict[str, tuple[list[float], list[float], list[str]]] = {
        "jamming onset": ([], [], []), "contact onset": ([], [], [])}
    for number, truth in enumerate(movements):
        rows = log.movement_index == truth.index
        if not rows.any():
            continue
        colour = palette[number % len(palette)]
        t = log.timestamps_s[rows]
        f = magnitude[rows]
        label = f"EM {truth.index + 1}, depth {100 * truth.depth_m:.2f} cm"
        ax_all.plot(t - truth.start_time_s, f, color=colour, lw=1.0, label=label)
        for name, onset in (("jamming onset", truth.jamming_onset_s),
                            ("contact onset", truth.contact_onset_s)):
            if not math.isnan(onset):
                k = min(int(np.searchsorted(t, onset)), f.size - 1)
                onsets[name][0].append(onset - truth.start_time_s)
                onsets[name][1].append(float(f[k]))
                onsets[name][2].append(colour)
        if not math.isnan(truth.jamming_onset_s):
            ax_aligned.plot(t - truth.jamming_onset_s, f, color=colour, lw=1.0)
    for (name, (xs, ys, colours)), marker in zip(onsets.items(), ("o", "X"), strict=True):
        if xs:
            ax_all.scatter(xs, ys, c=colours, marker=marker, s=45, edgecolors="black",
                           linewidths=0.6, zorder=3, label=name)
    if any(not math.isnan(m.jamming_onset_s) for m in movements):
        ax_aligned.axvline(0.0, color="k", ls="--", lw=1.0)
    for ax in (ax_all, ax_aligned):
        ax.set_ylabel("fingertip force (N)")
        ax.grid(alpha=0.3)
    ax_all.set_xlabel("time since movement start (s)")
    ax_all.set_title("force per movement")
    ax_aligned.set_xlabel("time since jamming onset (s)")
    ax_aligned.set_title("movements that jammed, aligned at onset")
    handles, labels = ax_all.get_legend_handles_labels()
    if labels:
        figure.legend(handles, labels, loc="upper left", fontsize=7, ncols=columns,
                      bbox_to_anchor=(_PANELS_IN[0] / width, 0.92), frameon=False)
    return figure


def _tab20() -> list[str]:
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    return [str(to_hex(colormaps["tab20"](i))) for i in range(20)]


def plot_movement_forces(
    log: GroundTruthLog, movements: Sequence[MovementTruth], path: Path
) -> Path | None:
    """Write :func:`draw_movement_forces` as PNG at ``path``.

    Returns
    -------
    Path or None
        The written file, or None when matplotlib is not installed (a warning says so).
    """
    try:
        figure = draw_movement_forces(log, movements)
    except ImportError:  # plots are an optional extra
        warnings.warn("matplotlib is not installed; forces.png was not written", stacklevel=2)
        return None
    return plotting.save_figure(figure, path)
